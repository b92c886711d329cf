"""Safety verdicts: each collision of each run judged against the ISO/TS 15066 limits of the body
region that was hit (:mod:`hilrig.world.body`; formulas and their sources in docs/safety.md).

Per Cartesian collision event (``start_s`` .. ``end_s``), with ``|F|`` the force's magnitude:

- the transient phase is the event's first ``transient_s`` (default 0.5 s); its peak is judged
  against the transient limit (twice the quasi-static force; no transient contact is permitted
  on the skull and face, so any contact there is over), the peak after it against the
  quasi-static limit;
- the pressure is ``|F| / contact area`` in the same two phases, against the region's strictest
  specific area (times two when transient);
- the energy transferred is ``E = F^2 / (2 k)`` at the peak force, ``k`` the region's spring
  constant (Table A.3);
- the robot's effective mass ``m_R`` along the force at the contact's onset (the pose and
  direction from the commanded joints and the force's direction at its peak), the reduced mass
  ``mu = 1 / (1/m_R + 1/m_H)`` with the region's mass ``m_H``, the maximum permissible relative
  speed ``v = F_max / sqrt(mu k)`` (``F_max`` the transient limit, Annex A.3) against the TCP's
  measured speed towards the body at the onset;
- the verdict is ``within`` when every judged value is at most its limit, else ``over``; the
  margin is the smallest ``100 (limit - value) / limit`` over them, and ``binding`` names it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.analysis.events import AxisGroup, CollisionEvent
from hilrig.analysis.sources import Run
from hilrig.errors import AnalysisError, ParameterError
from hilrig.robot import RobotModel
from hilrig.world.body import PROBE_AREA_CM2, BodyRegion, body_region

TRANSIENT_S = 0.5  # the transient phase's length, s (a convention; docs/safety.md)
SPEED_WINDOW_S = 0.02  # the TCP's speed at onset: its travel over this long before the onset
NAN = float("nan")


@dataclass(frozen=True)
class VerdictConfig:
    """What to judge against: the region (None: the session's), contact area and phase."""

    body_region: str | None = None
    contact_area_cm2: float | None = None  # None: the session's, else the standard's probe
    transient_s: float = TRANSIENT_S

    def __post_init__(self) -> None:
        if self.body_region is not None:
            try:
                body_region(self.body_region)
            except ParameterError as err:
                raise AnalysisError(f"--body-region: {err}") from None
        area = self.contact_area_cm2
        if area is not None and not (math.isfinite(area) and area > 0):
            raise AnalysisError(f"--contact-area-cm2 {area:g}: must be a finite area > 0")
        if not (math.isfinite(self.transient_s) and self.transient_s > 0):
            raise AnalysisError(f"--transient-s {self.transient_s:g}: must be a time > 0 s")


@dataclass(frozen=True)
class Verdict:
    """One run's collision judged (units in the names; NaN where a value cannot be had)."""

    run: str
    event: int
    body_region: str
    peak_force_n: float
    transient_peak_n: float
    quasi_static_peak_n: float
    transient_limit_n: float  # NaN: no transient contact permitted
    quasi_static_limit_n: float
    contact_area_cm2: float
    pressure_n_cm2: float
    transient_pressure_limit_n_cm2: float
    quasi_static_pressure_limit_n_cm2: float
    energy_j: float
    effective_mass_kg: float
    reduced_mass_kg: float
    approach_speed_m_s: float
    speed_limit_m_s: float
    verdict: str  # "within" or "over"
    margin_pct: float
    binding: str  # the judged quantity with the smallest margin


def judge(
    run: Run,
    events: Sequence[CollisionEvent],
    region: BodyRegion,
    area_cm2: float,
    transient_s: float,
    model: RobotModel,
) -> list[Verdict]:
    """The verdicts of ``run`` on the Cartesian ``events``."""
    cartesian = [run.axes.index(a) for a in ("x", "y", "z") if a in run.axes]
    if len(cartesian) != 3:
        return []
    verdicts = []
    for number, event in enumerate(events):
        if event.group is not AxisGroup.CARTESIAN:
            continue
        # the rows in [start_s, end_s]: t_s increases (a Run's invariant), so two binary
        # searches instead of masks over the whole run (20 events x 10 min cost 36 ms)
        first = int(np.searchsorted(run.t_s, event.start_s, side="left"))
        end = int(np.searchsorted(run.t_s, event.end_s, side="right"))
        if end <= first:
            continue
        t, force = run.t_s[first:end], run.force[first:end][:, cartesian]
        verdicts.append(_verdict(run, number, t, force, region, area_cm2, transient_s, model))
    return verdicts


def _verdict(
    run: Run,
    number: int,
    t_s: NDArray[np.float64],
    force: NDArray[np.float64],
    region: BodyRegion,
    area_cm2: float,
    transient_s: float,
    model: RobotModel,
) -> Verdict:
    magnitude = np.linalg.norm(force, axis=1)
    peak_at = int(np.argmax(magnitude))
    peak = float(magnitude[peak_at])
    early = t_s <= t_s[0] + transient_s
    transient_peak = float(magnitude[early].max())
    quasi_static_peak = float(magnitude[~early].max()) if (~early).any() else NAN
    transient_limit = region.transient_force_n
    k = region.spring_constant_n_m
    qs_pressure = region.quasi_static_pressure_n_cm2
    transient_pressure = 2.0 * qs_pressure if transient_limit is not None else NAN
    mass, speed = _robot_at_onset(run, t_s[0], force[peak_at], model)
    reduced = 1.0 / (1.0 / mass + 1.0 / region.effective_mass_kg) if mass > 0 else NAN
    speed_limit = transient_limit / math.sqrt(reduced * k) if transient_limit is not None else NAN
    checks = {
        "quasi-static force": (quasi_static_peak, region.quasi_static_force_n),
        "quasi-static pressure": (quasi_static_peak / area_cm2, qs_pressure),
        "approach speed": (speed, speed_limit),
    }
    if transient_limit is not None:
        checks["transient force"] = (transient_peak, transient_limit)
        checks["transient pressure"] = (transient_peak / area_cm2, transient_pressure)
    margins = {
        name: 100.0 * (limit - value) / limit
        for name, (value, limit) in checks.items()
        if math.isfinite(value) and math.isfinite(limit)
    }
    if transient_limit is None:  # skull, face: no transient contact is permissible
        binding, margin = "transient contact (not permitted)", -100.0
    else:
        binding = min(margins, key=margins.__getitem__)
        margin = margins[binding]
    return Verdict(
        run.name,
        number,
        region.name,
        peak,
        transient_peak,
        quasi_static_peak,
        NAN if transient_limit is None else transient_limit,
        region.quasi_static_force_n,
        area_cm2,
        peak / area_cm2,
        transient_pressure,
        qs_pressure,
        peak * peak / (2.0 * k),
        mass,
        reduced,
        speed,
        speed_limit,
        "within" if margin >= 0 else "over",
        margin,
        binding,
    )


def _robot_at_onset(
    run: Run, onset_s: float, force: NDArray[np.float64], model: RobotModel
) -> tuple[float, float]:
    """The arm's effective mass along the force (kg) and the TCP's speed towards the body
    (m/s, >= 0) at ``onset_s``, from the commanded joints; NaN, NaN without them."""
    times, joints = run.commanded_t_s, run.commanded_joints_rad
    size = float(np.linalg.norm(force))
    if times is None or joints is None or len(times) < 2 or size == 0.0:
        return NAN, NAN
    push = force / size  # the body pushes the robot along this
    at = int(np.clip(np.searchsorted(times, onset_s), 0, len(times) - 1))
    before = int(np.clip(np.searchsorted(times, onset_s - SPEED_WINDOW_S), 0, len(times) - 1))
    q = np.ascontiguousarray(joints[at])
    mass = model.effective_mass_kg(q, push)
    if at == before:
        return mass, NAN
    travel = model.fk(q)[:3, 3] - model.fk(np.ascontiguousarray(joints[before]))[:3, 3]
    toward = -float(travel @ push) / float(times[at] - times[before])
    return mass, max(toward, 0.0)


def region_of(config: VerdictConfig, recorded: str) -> tuple[BodyRegion | None, str]:
    """The region to judge against (the option over the recording's; None: neither) and where
    it came from."""
    name = config.body_region or recorded
    if not name:
        return None, "no body region given (record --body-region, analyze --body-region)"
    try:
        return body_region(name), "from --body-region" if config.body_region else "recorded"
    except ParameterError as err:
        raise AnalysisError(f"recorded body region: {err}") from None


def area_of(config: VerdictConfig, recorded: float | None) -> float:
    """The contact area, cm^2: the option's, else the recording's, else the standard's probe."""
    return config.contact_area_cm2 or recorded or PROBE_AREA_CM2
