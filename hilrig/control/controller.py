"""The public controller: ``make`` for the live loop, ``simulate`` for whole traces.

Both run the same compiled kernel (``kernel.run``) on the same packed state, so a session
replayed through ``simulate`` reproduces the offsets its live ``step`` calls commanded, bit for
bit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hilrig.control import kernel as K
from hilrig.control.params import (
    AdmittanceParams,
    AxisBounds,
    BetaReading,
    ChiReading,
    Integrator,
    Law,
    from_mapping,
    validate,
)
from hilrig.control.presets import preset
from hilrig.errors import NonFiniteForceError, ParameterError

ParamsLike = str | AdmittanceParams | Mapping[str, Any]


def resolve_params(params: ParamsLike) -> AdmittanceParams:
    """A params object from a preset name, an object, or a mapping (``preset`` key optional)."""
    if isinstance(params, AdmittanceParams):
        return params
    if isinstance(params, str):
        return preset(params)
    values = dict(params)
    base = values.pop("preset", None)
    return from_mapping(values, preset(base) if base is not None else None)


def _series_terms(theta: float) -> tuple[int, int]:
    """(Taylor terms, doublings) so that phi_1's series at ||A*h|| <= 0.5 is good to 1e-16."""
    nsq = max(0, math.ceil(math.log2(theta / 0.5))) if theta > 0.5 else 0
    theta /= 2.0**nsq
    terms = 1
    while theta**terms / math.factorial(terms + 1) > 1e-16 and terms < 30:
        terms += 1
    return terms, nsq


@dataclass(frozen=True)
class Packed:
    """Validated parameters packed for the kernel (see kernel.py for the row layout)."""

    law: Law
    params: AdmittanceParams
    axes: int
    dt: float
    P: NDArray[np.float64]
    cfg: NDArray[np.int64]
    bounds: AxisBounds

    @staticmethod
    def build(law: Law | str, params: ParamsLike, axes: int, dt: float) -> Packed:
        try:
            law = Law(law)
        except ValueError:
            known = ", ".join(v.value for v in Law)
            raise ParameterError(f"law {law!r} is not one of: {known}") from None
        resolved = resolve_params(params)
        found = validate(law, resolved, axes, dt)
        P = np.zeros((K.NP, axes))
        for row, name in ((K.M, "m"), (K.BD, "b_d"), (K.KD, "k_d"), (K.A1, "a1"), (K.A2, "a2")):
            P[row] = resolved.per_axis(name, axes)
        P[K.BETA] = resolved.per_axis("beta", axes)
        P[K.DELTA] = resolved.per_axis("delta", axes)
        P[K.BMIN] = found.b_min
        P[K.GROWTH] = np.exp(found.gamma * dt)
        P[K.TOL] = resolved.per_axis("settle_tol", axes)
        P[K.DT] = dt
        for i in range(axes):
            theta = dt * max(1.0, (found.k_max[i] + found.b_max[i]) / P[K.M, i])
            P[K.NTERMS, i], P[K.NSQ, i] = _series_terms(theta)
        cfg = np.zeros(K.NC + axes, dtype=np.int64)
        cfg[K.LAW] = list(Law).index(law)
        cfg[K.CHI] = list(ChiReading).index(resolved.chi)
        cfg[K.BETA_READING] = list(BetaReading).index(resolved.beta_reading)
        cfg[K.INTEGRATOR] = list(Integrator).index(resolved.integrator)
        cfg[K.SM] = int(resolved.state_machine)
        cfg[K.GUARD] = int(resolved.rate_guard)
        cfg[K.DEBOUNCE] = max(1, round(resolved.debounce_s / dt))
        cfg[K.RELEASE] = max(1, round(resolved.release_s / dt))
        cfg[K.HOLD] = max(1, round(resolved.hold_s / dt))
        groups = resolved.groups or (0,) * axes
        _, dense = np.unique(np.asarray(groups), return_inverse=True)  # groups -> 0..G-1
        cfg[K.NC :] = dense
        return Packed(law, resolved, axes, dt, P, cfg, found)

    def initial_state(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Float and group state at rest: e = e' = 0, nominal b_d, k_d, discretised."""
        S = np.zeros((K.NS, self.axes))
        S[K.B] = self.P[K.BD]
        S[K.K] = self.P[K.KD]
        zoh = self.params.integrator is Integrator.ZOH
        for i in range(self.axes):
            K.discretise(self.P, S, i, S[K.B, i], S[K.K, i], zoh)
        return S, np.zeros((K.NG, self.axes), dtype=np.int64)


def _refuse_nonfinite(force: NDArray[np.float64], tick_offset: int = 0) -> None:
    bad = ~np.isfinite(force)
    if bad.any():
        n, i = np.unravel_index(int(np.argmax(bad)), force.shape)
        raise NonFiniteForceError(
            f"force[{tick_offset + int(n)}, {int(i)}] is {force[n, i]}: non-finite force is "
            "refused and nothing from that tick on was integrated"
        )


class KernelArrays(NamedTuple):
    """A controller's compiled state, for compiled callers such as the rig's tick.

    ``run_compiled(force, P, cfg, S, G, out, contact)`` (:func:`hilrig.control.run_compiled`)
    advances the controller by one tick per row of ``force`` (1, A), exactly as ``step`` does;
    ``offset``, ``velocity``, ``damping``, ``stiffness`` (A,) are views of its results and
    ``mass`` (A,) the per-axis m (kg, or kg*m^2 on joints). Every array is the controller's own.
    """

    force: NDArray[np.float64]
    P: NDArray[np.float64]
    cfg: NDArray[np.int64]
    S: NDArray[np.float64]
    G: NDArray[np.int64]
    out: NDArray[np.float64]
    contact: NDArray[np.int8]
    offset: NDArray[np.float64]
    velocity: NDArray[np.float64]
    damping: NDArray[np.float64]
    stiffness: NDArray[np.float64]
    mass: NDArray[np.float64]


class AdmittanceController:
    """A per-tick admittance controller over ``axes`` axes (create it with :func:`make`).

    ``step(force_row)`` takes this tick's force/torque per axis (N, N*m) and returns the offsets
    e (m, rad) to command at this tick, i.e. e(t_n + dt). The returned array is the controller's
    own buffer, overwritten by the next step (copy it to keep it); nothing is allocated per tick.
    """

    def __init__(self, packed: Packed) -> None:
        self._packed = packed
        self._force = np.zeros((1, packed.axes))
        self._out = np.zeros((K.NO, 1, packed.axes))
        self._contact = np.zeros((1, packed.axes), dtype=np.int8)
        self._S, self._G = packed.initial_state()
        self._ticks = 0
        # Typed views into the buffers the kernel writes; step() returns _offset itself.
        self._offset: NDArray[np.float64] = self._out[K.OUT_OFFSET, 0]
        self._velocity: NDArray[np.float64] = self._out[K.OUT_VELOCITY, 0]
        self._damping: NDArray[np.float64] = self._out[K.OUT_DAMPING, 0]
        self._stiffness: NDArray[np.float64] = self._out[K.OUT_STIFFNESS, 0]
        self._m = packed.P[K.M]
        self._contact_row: NDArray[np.int8] = self._contact[0]

    @property
    def law(self) -> Law:
        return self._packed.law

    @property
    def params(self) -> AdmittanceParams:
        return self._packed.params

    @property
    def axes(self) -> int:
        return self._packed.axes

    @property
    def dt(self) -> float:
        return self._packed.dt

    @property
    def bounds(self) -> AxisBounds:
        return self._packed.bounds

    def reset(self) -> None:
        """Back to rest (zero offset, nominal parameters, every group free)."""
        S, G = self._packed.initial_state()
        self._S[:] = S
        self._G[:] = G
        self._out[:] = 0.0
        self._contact[:] = 0
        self._ticks = 0

    def kernel_arrays(self) -> KernelArrays:
        """The arrays a compiled caller passes to ``run_compiled`` (see :class:`KernelArrays`)."""
        p = self._packed
        return KernelArrays(
            self._force,
            p.P,
            p.cfg,
            self._S,
            self._G,
            self._out,
            self._contact,
            self._offset,
            self._velocity,
            self._damping,
            self._stiffness,
            self._m,
        )

    def step(self, force_row: ArrayLike) -> NDArray[np.float64]:
        """Advance one tick with force_row (axes,); raises NonFiniteForceError on NaN/inf."""
        self._force[0] = force_row
        code = K.run(
            self._force,
            self._packed.P,
            self._packed.cfg,
            self._S,
            self._G,
            self._out,
            self._contact,
        )
        if code >= 0:
            _refuse_nonfinite(self._force, self._ticks)
        self._ticks += 1
        return self._offset

    @property
    def offset(self) -> NDArray[np.float64]:
        """e after the last step (m, rad): what ``step`` returned."""
        return self._offset

    @property
    def velocity(self) -> NDArray[np.float64]:
        """e' after the last step (m/s, rad/s)."""
        return self._velocity

    @property
    def damping(self) -> NDArray[np.float64]:
        """b used over the last step."""
        return self._damping

    @property
    def stiffness(self) -> NDArray[np.float64]:
        """k used over the last step."""
        return self._stiffness

    @property
    def zeta(self) -> NDArray[np.float64]:
        """Damping ratio b/(2*sqrt(m*k)) of the last step (allocates: not for the tick)."""
        zeta: NDArray[np.float64] = self._damping / (2.0 * np.sqrt(self._m * self._stiffness))
        return zeta

    @property
    def contact(self) -> NDArray[np.int8]:
        """ContactState code of each axis's group after the last step."""
        return self._contact_row


def make(
    law: Law | str,
    params: ParamsLike = "adaptive",
    axes: int | None = None,
    dt: float = 0.001,
) -> AdmittanceController:
    """A controller for the live loop; ``axes`` defaults to the length of per-axis params.

    Raises ParameterError when the parameters are invalid or cannot be stable.
    """
    resolved = resolve_params(params)
    if axes is None:
        axes = resolved.axes()
        if axes is None:
            raise ParameterError("axes is required when every parameter is a single value")
    return AdmittanceController(Packed.build(law, resolved, axes, dt))


@dataclass(frozen=True)
class SimResult:
    """A whole-trace simulation; every array is (T, A), row n belonging to tick n.

    ``offset[n]`` is the offset commanded at tick n, e(t_n + dt) (m or rad), ``velocity[n]`` its
    rate, ``damping``/``stiffness`` the b, k held over tick n, ``zeta`` the damping ratio and
    ``contact`` the ContactState code of the axis's group.
    """

    law: Law
    params: AdmittanceParams
    dt: float
    offset: NDArray[np.float64]
    velocity: NDArray[np.float64]
    damping: NDArray[np.float64]
    stiffness: NDArray[np.float64]
    contact: NDArray[np.int8]

    @property
    def t(self) -> NDArray[np.float64]:
        """Time of each tick's start, s (the offset belongs to t + dt)."""
        return np.arange(self.offset.shape[0], dtype=np.float64) * self.dt

    @property
    def zeta(self) -> NDArray[np.float64]:
        """Damping ratio b/(2*sqrt(m*k)) per tick and axis (bit-equal to the live value)."""
        m = self.params.per_axis("m", self.offset.shape[1])
        return self.damping / (2.0 * np.sqrt(m * self.stiffness))

    @property
    def omega_n(self) -> NDArray[np.float64]:
        """Undamped natural frequency sqrt(k/m) per tick and axis, rad/s."""
        m = self.params.per_axis("m", self.offset.shape[1])
        return np.sqrt(self.stiffness / m)


def simulate(
    law: Law | str | AdmittanceController,
    force: ArrayLike,
    dt: float | None = None,
    params: ParamsLike | None = None,
) -> SimResult:
    """Run a whole force trace (T, A) (or (T,) for one axis) through a controller from rest.

    ``law`` is a law name or a controller (whose law, params and dt are used; it is not
    modified). Raises NonFiniteForceError before integrating anything if force has NaN/inf,
    ParameterError for invalid or unstable parameters.
    """
    trace = np.ascontiguousarray(force, dtype=np.float64)
    if trace.ndim == 1:
        trace = trace[:, None]
    if trace.ndim != 2:
        raise ParameterError(f"force must be (T, axes), got shape {trace.shape}")
    if isinstance(law, AdmittanceController):
        if params is not None or (dt is not None and dt != law.dt):
            raise ParameterError("pass either a controller or law/params/dt, not both")
        packed = law._packed
        if packed.axes != trace.shape[1]:
            raise ParameterError(f"controller has {packed.axes} axes, force has {trace.shape[1]}")
    else:
        if dt is None or params is None:
            raise ParameterError("dt and params are required with a law name")
        packed = Packed.build(law, params, trace.shape[1], dt)
    _refuse_nonfinite(trace)
    T, A = trace.shape
    out = np.empty((K.NO, T, A))
    contact = np.empty((T, A), dtype=np.int8)
    S, G = packed.initial_state()
    K.run(trace, packed.P, packed.cfg, S, G, out, contact)
    return SimResult(
        packed.law,
        packed.params,
        packed.dt,
        out[K.OUT_OFFSET],
        out[K.OUT_VELOCITY],
        out[K.OUT_DAMPING],
        out[K.OUT_STIFFNESS],
        contact,
    )


def gains(
    law: Law | str, force: ArrayLike, params: ParamsLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The bare law's damping and stiffness for each row of force (T, A), no state machine."""
    trace = np.ascontiguousarray(force, dtype=np.float64)
    if trace.ndim == 1:
        trace = trace[:, None]
    packed = Packed.build(law, params, trace.shape[1], 1e-3)
    _refuse_nonfinite(trace)
    b = np.empty_like(trace)
    k = np.empty_like(trace)
    cfg = packed.cfg
    K.gains(
        int(cfg[K.LAW]),
        int(cfg[K.CHI]),
        int(cfg[K.BETA_READING]),
        packed.P,
        cfg[K.NC :].copy(),
        trace,
        b,
        k,
    )
    return b, k
