"""Contact models: what the robot touched, identified from a collision's force and motion.

Along the collision's direction ``u`` (base frame), the force the robot felt is
``f(t) = F(t).u`` and the tool's travel ``y(t) = (x(t) - x(t_on)).u``. The body that was hit
has a surface at ``h(t)`` along ``u`` (approach at ``v_in``, hold at its deepest ``h_max``
between ``t_full`` and ``t_back``, withdraw at ``v_out``) and pushes on the penetration
``p = h - y``:

- spring-damper: ``f = max(0, k p + c p')`` (N/m, N*s/m);
- Hunt-Crossley: ``f = max(0, k p^n + lam p^n p')`` for ``p > 0`` (Hunt and Crossley, 1975;
  ``n = 1.5``, Hertzian contact);
- force source: ``f(t)`` as recorded, whatever the robot does (the paper's scripted profiles).

:func:`fit_contact` fits both mechanics by least squares (``scipy.optimize.least_squares``) over
the contact phase (from the first to the last sample above ``ONSET_SHARE`` of the peak and clear
of the noise at the window's edges) and keeps the one with the smaller residual. Whether the
robot's motion matters at all is asked by fitting the same mechanics once more as if the tool
had not moved: a body the robot pushes into is explained far better with the tool's travel, a
scripted force (the paper's profiles) about as well without it. When the motion improves the fit
(residual sum of squares) by less than ``SOURCE_GAIN`` times and the fit is good (R^2 at least
``MIN_R2``), the body is a force source. The fit's R^2 and RMS residual (N) come with it;
:meth:`ContactFit.check` refuses a prediction from a poor fit in one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from hilrig.errors import ParameterError

Vector = NDArray[np.float64]

HUNT_CROSSLEY_N = 1.5
SOURCE_GAIN = 3.0  # the tool's travel improves a body's fit less than this many times: a source
MIN_R2 = 0.9  # a fit poorer than this is not used to predict
MAX_RMS_SHARE = 0.1  # nor one whose RMS residual exceeds this share of the peak force
ONSET_SHARE = 0.02  # the contact phase: where |F| exceeds this share of its peak,
NOISE_MARGIN = 1.5  # and this many times the largest |F| in the first and last tenth of the
MAX_ONSET_SHARE = 0.2  # window (its noise), but never more than this share of the peak


class Mechanics(StrEnum):
    SPRING_DAMPER = "spring-damper"
    HUNT_CROSSLEY = "hunt-crossley"
    FORCE_SOURCE = "force-source"


@dataclass(frozen=True)
class SurfaceMotion:
    """Where the body's surface is along ``u`` (m, from the tool at onset): ``h(t)``."""

    t_full_s: float  # reaches its deepest point
    t_back_s: float  # starts to withdraw
    h_max_m: float
    v_in_m_s: float
    v_out_m_s: float

    def at(self, t_s: Vector) -> tuple[Vector, Vector]:
        """``h(t)`` (m) and ``h'(t)`` (m/s)."""
        before, after = t_s < self.t_full_s, t_s > self.t_back_s
        h = np.full_like(t_s, self.h_max_m)
        rate = np.zeros_like(t_s)
        h[before] -= self.v_in_m_s * (self.t_full_s - t_s[before])
        rate[before] = self.v_in_m_s
        h[after] -= self.v_out_m_s * (t_s[after] - self.t_back_s)
        rate[after] = -self.v_out_m_s
        return h, rate


@dataclass(frozen=True)
class ContactModel:
    """A fitted body: mechanics and their coefficients, its surface's motion, the direction
    ``u`` (unit, base frame) and, for a force source, the recorded force along ``u``."""

    mechanics: Mechanics
    direction_in_base: tuple[float, float, float]
    stiffness: float = 0.0  # N/m (spring-damper) or N/m^n (Hunt-Crossley)
    damping: float = 0.0  # N*s/m (spring-damper) or s/m (Hunt-Crossley's lam)
    motion: SurfaceMotion | None = None

    def force(self, penetration_m: Vector, rate_m_s: Vector) -> Vector:
        """The push (N, >= 0) for penetrations and their rates (not for a force source)."""
        p = np.maximum(penetration_m, 0.0)
        if self.mechanics is Mechanics.SPRING_DAMPER:
            push = self.stiffness * p + self.damping * rate_m_s
        elif self.mechanics is Mechanics.HUNT_CROSSLEY:
            pn = p**HUNT_CROSSLEY_N
            push = self.stiffness * pn * (1.0 + self.damping * rate_m_s)
        else:
            raise ParameterError("a force source's force is its recording, not a function")
        return np.where(penetration_m > 0.0, np.maximum(push, 0.0), 0.0)


@dataclass(frozen=True)
class ContactFit:
    """A contact model and how well it explains the event's force."""

    model: ContactModel
    r2: float
    rms_n: float
    peak_n: float
    motion_gain: float  # how many times better the fit is with the robot's motion (module)
    t_on_s: float
    t_off_s: float

    def check(self, event: str) -> None:
        """Raise ParameterError (one line, naming ``event`` and the figure) for a poor fit."""
        if not self.r2 >= MIN_R2:
            raise ParameterError(
                f"{event}: the contact model explains too little of the force (R^2 {self.r2:.2f}"
                f" < {MIN_R2}); no closed-loop prediction"
            )
        if not self.rms_n <= MAX_RMS_SHARE * self.peak_n:
            raise ParameterError(
                f"{event}: the contact model's RMS residual {self.rms_n:.2f} N is over"
                f" {100 * MAX_RMS_SHARE:.0f} % of the peak force {self.peak_n:.2f} N; no"
                " closed-loop prediction"
            )


def fit_contact(
    t_s: Vector, force_base_n: Vector, tool_base_m: Vector, *, mechanics: Mechanics | None = None
) -> ContactFit:
    """Fit the body one collision touched, from its force (n, 3) N and the tool's position
    (n, 3) m in the base frame at times ``t_s`` (n,) s, covering the collision. ``mechanics``
    asks for one model (a force source is then not looked for); None fits both and keeps the
    better. Raises ParameterError (one line) when there is no contact phase to fit."""
    t_s = np.asarray(t_s, dtype=np.float64)
    force = np.asarray(force_base_n, dtype=np.float64)
    tool = np.asarray(tool_base_m, dtype=np.float64)
    magnitude = np.linalg.norm(force, axis=1)
    peak = float(magnitude.max(initial=0.0))
    if not (len(t_s) >= 10 and math.isfinite(peak) and peak > 0.0):
        raise ParameterError("no contact force to fit a contact model to")
    # the contact phase: from the first to the last sample above ONSET_SHARE of the peak and
    # clear of the noise at the window's edges (a yielding robot may leave the body and come
    # back to it within one collision)
    edge = max(len(t_s) // 10, 1)
    noise = float(max(magnitude[:edge].max(), magnitude[-edge:].max()))
    threshold = min(max(ONSET_SHARE * peak, NOISE_MARGIN * noise), MAX_ONSET_SHARE * peak)
    phase = np.flatnonzero(magnitude > threshold)
    on, off = int(phase[0]), int(phase[-1]) + 1
    mean = force[on:off].mean(axis=0)
    u = mean / np.linalg.norm(mean)
    # fitted with a margin of a tenth of the phase each side: no force must be made there
    margin = max((off - on) // 10, 1)
    lo, hi = max(on - margin, 0), min(off + margin, len(t_s))
    t = t_s[lo:hi]
    f = force[lo:hi] @ u
    y = (tool[lo:hi] - tool[on]) @ u
    y_rate = np.gradient(y, t)
    direction = (float(u[0]), float(u[1]), float(u[2]))
    within = slice(on - lo, off - lo)
    bounds = (float(t_s[on]), float(t_s[off - 1]), float(y[within.start]))
    if mechanics is Mechanics.FORCE_SOURCE:
        return ContactFit(ContactModel(mechanics, direction), 1.0, 0.0, peak, 0.0, *bounds[:2])
    kinds = _MECHANICS if mechanics is None else (mechanics,)
    fits = [_fit(kind, direction, t, f, y, y_rate, bounds) for kind in kinds]
    model, residual = min(fits, key=lambda fit: float(np.sum(fit[1] ** 2)))
    inside, f_in = residual[within], f[within]
    total = float(np.sum((f_in - f_in.mean()) ** 2))
    r2 = 1.0 - float(np.sum(inside**2)) / total if total > 0 else 0.0
    rms = float(np.sqrt(np.mean(inside**2)))
    still = np.zeros_like(y)
    _, residual_still = _fit(model.mechanics, direction, t, f, still, still, (*bounds[:2], 0.0))
    gain = float(np.sum(residual_still[within] ** 2)) / max(float(np.sum(inside**2)), 1e-300)
    if gain < SOURCE_GAIN and mechanics is None and r2 >= MIN_R2:
        model = ContactModel(Mechanics.FORCE_SOURCE, direction)
        r2, rms = 1.0, 0.0
    return ContactFit(model, r2, rms, peak, gain, bounds[0], bounds[1])


_MECHANICS = (Mechanics.SPRING_DAMPER, Mechanics.HUNT_CROSSLEY)


def _fit(
    kind: Mechanics,
    direction: tuple[float, float, float],
    t: Vector,
    f: Vector,
    y: Vector,
    y_rate: Vector,
    phase: tuple[float, float, float],
) -> tuple[ContactModel, Vector]:
    """The best model of ``kind`` over a few starts, and its residual (N); ``phase`` is the
    contact's start and end (s) and the tool's travel at its start (m).

    The surface meets the tool where the force starts (p = 0 at the phase's start), which fixes
    its approach speed; the free parameters are log k, the damping, the time it is deepest, how
    long it holds there, that depth and the withdrawal speed (a damped contact lets go before
    the surface leaves: the force ends while p > 0)."""
    t_on, t_off, y_on = phase
    span = max(t_off - t_on, 1e-3)
    scale = max(float(f.max()), 1e-6)
    lower = np.array([np.log(1e-3), 0.0, t_on + 1e-3 * span, 0.0, float(y.min()), 1e-4])
    upper = np.array([np.log(1e9), 1e4, t_off - 1e-3 * span, span, float(y.max()) + 1.0, 10.0])
    best: tuple[ContactModel, Vector] | None = None
    # starts: fixed shapes from the tool's deepest travel, and from the force's peak (deepest
    # there, then held to the end or not at all) - a yielding robot travels furthest after it
    peak = int(np.argmax(f))
    at_peak = min(max((float(t[peak]) - t_on) / span, 0.01), 0.99)
    timings = [(0.3, 0.2, y.max()), (0.5, 0.0, y.max()), (0.2, 0.5, y.max()),
               (at_peak, 0.0, y[peak]), (at_peak, 0.9 * (1.0 - at_peak), y[peak])]  # fmt: skip
    for stiffness in (30.0, 300.0, 3000.0, 30000.0):
        depth = (
            scale / stiffness
            if kind is Mechanics.SPRING_DAMPER
            else (scale / stiffness) ** (1 / HUNT_CROSSLEY_N)
        )
        for at, hold, travel in timings:
            guess = np.array([np.log(stiffness), 0.0, t_on + at * span, hold * span,
                              float(travel) + depth, depth / span])  # fmt: skip
            guess = np.clip(guess, lower + 1e-9, upper - 1e-9)

            def residual(theta: Vector) -> Vector:
                model = _model(kind, direction, theta, t_on, t_off, y_on)
                return model.force(*_penetration(model, t, y, y_rate)) - f

            solution = least_squares(residual, guess, bounds=(lower, upper), x_scale="jac")
            if best is None or np.sum(solution.fun**2) < np.sum(best[1] ** 2):
                best = (_model(kind, direction, solution.x, t_on, t_off, y_on), solution.fun)
    assert best is not None
    return best


def _model(
    kind: Mechanics,
    direction: tuple[float, float, float],
    theta: Vector,
    t_on: float,
    t_off: float,
    y_on: float,
) -> ContactModel:
    log_k, c, t_full, hold, h_max, v_out = (float(v) for v in theta)
    t_back = min(t_full + hold, t_off)
    v_in = max(h_max - y_on, 0.0) / max(t_full - t_on, 1e-9)
    motion = SurfaceMotion(t_full, t_back, h_max, v_in, v_out)
    return ContactModel(kind, direction, math.exp(log_k), c, motion)


def _penetration(
    model: ContactModel, t: Vector, y: Vector, y_rate: Vector
) -> tuple[Vector, Vector]:
    assert model.motion is not None
    h, h_rate = model.motion.at(t)
    return h - y, h_rate - y_rate
