"""Admittance parameters: the typed record, its readings of the paper, and stability refusal.

Units: ``m`` in kg (kg*m^2 for joints, which the paper also writes as kg), ``b_d`` in N*s/m
(N*m*s/rad), ``k_d`` in N/m (N*m/rad), ``a1`` in N*s/m per N, ``a2`` dimensionless, ``beta`` like
``b_d``, ``delta`` in N (N*m), times in s. Every numeric field is one value for all axes or a
tuple with one value per axis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from enum import StrEnum
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import ParameterError

PerAxis = float | tuple[float, ...]
_Member = TypeVar("_Member", bound=StrEnum)


class Law(StrEnum):
    """The three admittance laws (docs/control.md, The law, per axis)."""

    FIXED = "fixed"
    VARIABLE_STIFFNESS = "variable-stiffness"
    ADAPTIVE = "adaptive"


class ChiReading(StrEnum):
    """How the stiffness weight chi_i of eq. (5) is read from the garbled PDF."""

    SQUARE = "square"  # chi_i = tanh(f_i**2)  (hilrig's reading, the default: docs/control.md)
    ABS = "abs"  # chi_i = tanh(|f_i|)   (the "2" read as a norm subscript)
    GROUP_SQUARE = (
        "group-square"  # chi = tanh(|f|**2) over the axis group ("no force in any direction")
    )


class BetaReading(StrEnum):
    """How beta bounds the damping reduction of eq. (4)."""

    CAP = "cap"  # b = b_d - min(a1*|f|, beta) above delta  (section 2.3: b_d - beta >= b_min > 0)
    MAX = "max"  # b = b_d - max(reduction, beta), as printed; floored at b_min


class Integrator(StrEnum):
    """Discretisation of the frozen-parameter system over one tick."""

    ZOH = "zoh"  # exact zero-order hold (default)
    EULER = "euler"  # semi-implicit (symplectic) Euler


@dataclass(frozen=True)
class AdmittanceParams:
    """Parameters of one admittance controller (any number of axes).

    The bare law is ``m*e'' + b(t)*e' + k(t)*e = f`` per axis; ``state_machine`` adds Algorithm 2
    (contact, holding, recovering) per axis group and ``rate_guard`` the Theorem 1 limit on how
    fast stiffness may rise (``gamma`` in 1/s, default 90 % of the theorem's bound).
    """

    m: PerAxis
    b_d: PerAxis
    k_d: PerAxis
    a1: PerAxis = 0.0
    a2: PerAxis = 0.0
    beta: PerAxis = 0.0
    delta: PerAxis = 0.0
    b_min: PerAxis | None = None
    gamma: PerAxis | None = None
    chi: ChiReading = ChiReading.SQUARE
    beta_reading: BetaReading = BetaReading.CAP
    integrator: Integrator = Integrator.ZOH
    state_machine: bool = False
    rate_guard: bool = False
    debounce_s: float = 0.004
    release_s: float = 0.05
    hold_s: float = 0.5
    settle_tol: PerAxis = 1e-3
    groups: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        for name in _PER_AXIS:
            value = getattr(self, name)
            if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str):
                try:
                    object.__setattr__(self, name, tuple(float(v) for v in value))
                except (TypeError, ValueError):
                    raise ParameterError(f"{name} = {value!r} must be numbers") from None
        for name, enum in (
            ("chi", ChiReading),
            ("beta_reading", BetaReading),
            ("integrator", Integrator),
        ):
            value = getattr(self, name)
            object.__setattr__(self, name, _member(enum, value, f"{name} = {value!r}"))
        if self.groups is not None:
            try:
                object.__setattr__(self, "groups", tuple(int(g) for g in self.groups))
            except (TypeError, ValueError):
                raise ParameterError(f"groups = {self.groups!r} must be integers") from None

    def with_(self, **overrides: Any) -> AdmittanceParams:
        """A copy with some fields replaced (unknown names raise ParameterError)."""
        _check_names(overrides)
        return replace(self, **overrides)

    def axes(self) -> int | None:
        """The axis count fixed by per-axis tuples, or None when every field is a scalar."""
        lengths = {len(v) for n in _PER_AXIS if isinstance(v := getattr(self, n), tuple)}
        if self.groups is not None:
            lengths.add(len(self.groups))
        if len(lengths) > 1:
            raise ParameterError(f"per-axis parameters have different lengths {sorted(lengths)}")
        return lengths.pop() if lengths else None

    def per_axis(self, name: str, axes: int) -> NDArray[np.float64]:
        """Field ``name`` broadcast to ``axes`` values (float64)."""
        value = getattr(self, name)
        out = np.empty(axes, dtype=np.float64)
        out[:] = np.nan if value is None else value
        return out


_PER_AXIS = (
    "m",
    "b_d",
    "k_d",
    "a1",
    "a2",
    "beta",
    "delta",
    "b_min",
    "gamma",
    "settle_tol",
)
FIELD_NAMES = tuple(f.name for f in fields(AdmittanceParams))


def _check_names(values: Mapping[str, Any]) -> None:
    unknown = sorted(set(values) - set(FIELD_NAMES))
    if unknown:
        raise ParameterError(f"unknown parameter {unknown[0]!r}; known: {', '.join(FIELD_NAMES)}")


def parse_law(value: Law | str) -> Law:
    """``value`` as a Law; ParameterError naming the laws otherwise."""
    return _member(Law, value, f"law {value!r}")


def _member(enum: type[_Member], value: Any, what: str) -> _Member:
    try:
        return enum(value)
    except ValueError:
        known = ", ".join(e.value for e in enum)
        raise ParameterError(f"{what} is not one of: {known}") from None


def from_mapping(values: Mapping[str, Any], base: AdmittanceParams | None) -> AdmittanceParams:
    """Build params from a mapping of field names, on top of ``base`` when one is given."""
    _check_names(values)
    if base is not None:
        return replace(base, **values)
    missing = [n for n in ("m", "b_d", "k_d") if n not in values]
    if missing:
        raise ParameterError(f"params need {', '.join(missing)} (or a 'preset' to start from)")
    return AdmittanceParams(**values)


def combine(*parts: tuple[AdmittanceParams, int]) -> AdmittanceParams:
    """Stack several parameter sets into one controller, each part its own axis group.

    ``combine((ee, 3), (joints, 6))`` gives 9 axes: 3 Cartesian (group 0), 6 joints (group 1).
    Options (readings, integrator, state machine, guard, timing) must agree between parts.
    """
    if not parts:
        raise ParameterError("combine needs at least one (params, axes) part")
    first = parts[0][0]
    shared: tuple[str, ...] = ("chi", "beta_reading", "integrator", "state_machine")
    shared += ("rate_guard", "debounce_s", "release_s", "hold_s")
    for params, _ in parts[1:]:
        for name in shared:
            if getattr(params, name) != getattr(first, name):
                raise ParameterError(
                    f"cannot combine params with different {name}: "
                    f"{getattr(first, name)!r} and {getattr(params, name)!r}"
                )
    stacked: dict[str, Any] = {}
    for name in _PER_AXIS:
        columns = [p.per_axis(name, n) for p, n in parts]
        merged = np.concatenate(columns)
        stacked[name] = None if np.isnan(merged).all() else tuple(merged)
        if stacked[name] is not None and np.isnan(merged).any():
            raise ParameterError(f"{name} is set for some parts of the combination and not others")
    groups: list[int] = []
    for index, (_, n) in enumerate(parts):
        groups.extend([index] * n)
    return replace(first, **stacked, groups=tuple(groups))


@dataclass(frozen=True)
class AxisBounds:
    """What the law can do on each axis (arrays of length ``axes``), in the params' units."""

    b_min: NDArray[np.float64]
    b_max: NDArray[np.float64]
    k_min: NDArray[np.float64]
    k_max: NDArray[np.float64]
    gamma: NDArray[np.float64]  # the stiffness rise rate used by the guard, 1/s
    gamma_bound: NDArray[np.float64]  # Theorem 1: 2*b_min*k_min/(m*k_max), 1/s


def bounds(law: Law, params: AdmittanceParams, axes: int) -> AxisBounds:
    """The damping and stiffness ranges the law can command; validates nothing."""
    b_d = params.per_axis("b_d", axes)
    k_d = params.per_axis("k_d", axes)
    m = params.per_axis("m", axes)
    b_min = b_d.copy()
    if law is Law.ADAPTIVE:
        b_min = b_d - params.per_axis("beta", axes)
        if params.beta_reading is BetaReading.MAX:
            floor = params.per_axis("b_min", axes)
            b_min = np.where(np.isnan(floor), 0.1 * b_d, floor)
    k_min = k_d.copy()
    if law is not Law.FIXED:
        k_min = (1.0 - params.per_axis("a2", axes)) * k_d
    with np.errstate(all="ignore"):  # extreme values: validate refuses them, naming which
        gamma_bound = 2.0 * b_min * k_min / (m * k_d)
    gamma = params.per_axis("gamma", axes)
    gamma = np.where(np.isnan(gamma), 0.9 * gamma_bound, gamma)
    return AxisBounds(b_min, b_d.copy(), k_min, k_d.copy(), gamma, gamma_bound)


def validate(law: Law, params: AdmittanceParams, axes: int, dt: float) -> AxisBounds:
    """Refuse parameters that are invalid or cannot be stable; returns the law's bounds.

    Raises ParameterError naming the parameter, its value, the axis and the bound it breaks.
    """
    if not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt = {dt!r} s must be finite and > 0")
    if axes < 1:
        raise ParameterError(f"axes = {axes} must be >= 1")
    declared = params.axes()
    if declared is not None and declared != axes:
        raise ParameterError(f"params are given for {declared} axes but the input has {axes}")
    for name in _PER_AXIS:
        values = params.per_axis(name, axes)
        bad = ~np.isfinite(values) & ~(np.isnan(values) & (getattr(params, name) is None))
        if bad.any():
            i = int(np.argmax(bad))
            raise ParameterError(f"{name} = {float(values[i])} on axis {i} must be finite")

    def require(ok: NDArray[np.bool_], what: str, values: NDArray[np.float64], bound: str) -> None:
        if not ok.all():
            i = int(np.argmin(ok))
            raise ParameterError(f"{what} = {values[i]:g} on axis {i} must be {bound}")

    m, b_d, k_d = (params.per_axis(n, axes) for n in ("m", "b_d", "k_d"))
    require(m > 0, "m", m, "> 0 (virtual inertia)")
    require(b_d > 0, "b_d", b_d, "> 0 (a fixed-parameter axis is stable iff m, b, k > 0)")
    require(k_d > 0, "k_d", k_d, "> 0 (a fixed-parameter axis is stable iff m, b, k > 0)")
    a2 = params.per_axis("a2", axes)
    if law is not Law.FIXED:
        require((a2 >= 0) & (a2 < 1), "a2", a2, "in [0, 1) so that k_min = (1 - a2)*k_d > 0")
    if law is Law.ADAPTIVE:
        for name in ("a1", "beta", "delta"):
            values = params.per_axis(name, axes)
            require(values >= 0, name, values, ">= 0")
        beta = params.per_axis("beta", axes)
        if params.beta_reading is BetaReading.CAP:
            require(
                beta < b_d, "beta", beta, "< b_d so that the smallest damping b_d - beta stays > 0"
            )
    found = bounds(law, params, axes)
    if law is Law.ADAPTIVE and params.beta_reading is BetaReading.MAX:
        require(found.b_min > 0, "b_min", found.b_min, "> 0")
        require(found.b_min <= b_d, "b_min", found.b_min, "<= b_d")
    settle = params.per_axis("settle_tol", axes)
    require(settle > 0, "settle_tol", settle, "> 0")
    for name in ("debounce_s", "release_s", "hold_s"):
        value = float(getattr(params, name))
        if not (math.isfinite(value) and value >= 0):
            raise ParameterError(f"{name} = {value!r} s must be finite and >= 0")
        if value / dt > MAX_TICKS:
            raise ParameterError(
                f"{name} = {value:g} s must be at most 2**53 ticks of dt = {dt:g} s "
                f"({MAX_TICKS * dt:g} s)"
            )
    if params.rate_guard:
        require(found.gamma > 0, "gamma", found.gamma, "> 0")
        require(
            found.gamma < found.gamma_bound,
            "gamma",
            found.gamma,
            "< 2*b_min*k_min/(m*k_max) (Theorem 1), here "
            + ", ".join(f"{g:g}" for g in found.gamma_bound)
            + " 1/s",
        )
    if params.integrator is Integrator.EULER:
        # Semi-implicit Euler on m*e'' + b*e' + k*e: stable iff k*dt^2/m + 2*b*dt/m < 4
        # (and b*dt/m < 2); the worst case over the law's range is at k_max, b_max.
        margin = found.k_max * dt * dt / m + 2.0 * found.b_max * dt / m
        require(
            margin < 4.0,
            "k_max*dt^2/m + 2*b_max*dt/m",
            margin,
            "< 4 for semi-implicit Euler to be stable (use a smaller dt or integrator 'zoh')",
        )
    _check_discretisation(params.integrator, m, found, dt)
    if params.groups is not None:
        groups = np.asarray(params.groups)
        if (groups < 0).any():
            raise ParameterError(f"groups = {params.groups} must be >= 0")
    return found


#: Largest dt*(b + k)/m of the exact (zoh) discretisation. Its closed form stays finite beyond,
#: but a few ulp of the inputs move exp(A dt) by about ||A dt||^2 ulp (1e-4 relative here), so
#: such a step no longer resolves the dynamics it discretises.
MAX_STEP_STIFFNESS = 1e6
#: Least fraction by which the slowest mode must decay per tick: below it the discretised
#: filter's spectral radius is 1 in float64 and an offset would never return to rest.
MIN_DECAY_PER_TICK = 1e-12
#: Longest state-machine time, in ticks (counted in int64, converted from float64 exactly).
MAX_TICKS = 2**53


def _check_discretisation(
    integrator: Integrator, m: NDArray[np.float64], found: AxisBounds, dt: float
) -> None:
    """Refuse an axis whose discretised filter would not be finite, or would not return to rest
    in float64, anywhere in the law's range of b and k (its corners)."""
    for i in range(m.shape[0]):
        b_max, k_max = float(found.b_max[i]), float(found.k_max[i])
        if integrator is Integrator.ZOH:
            rate = (k_max + b_max) / m[i]
            if not dt * rate <= MAX_STEP_STIFFNESS:
                raise ParameterError(
                    f"m = {m[i]:g}, b_d = {b_max:g}, k_d = {k_max:g} on axis {i}: "
                    f"dt*(b_d + k_d)/m = {dt * rate:.3g} at dt = {dt:g} s must be <= "
                    f"{MAX_STEP_STIFFNESS:g}, or the discretised filter loses its precision "
                    "and overflows"
                )
        corners = (
            ("b_min", float(found.b_min[i]), "k_min", float(found.k_min[i])),
            ("b_min", float(found.b_min[i]), "k_d", k_max),
            ("b_d", b_max, "k_min", float(found.k_min[i])),
            ("b_d", b_max, "k_d", k_max),
        )
        for b_name, b, k_name, k in corners:
            with np.errstate(divide="ignore", over="ignore"):  # damping_ratio's formula
                zeta = float(np.float64(b) / (2.0 * np.sqrt(k * m[i])))
            if not math.isfinite(zeta):
                raise ParameterError(
                    f"m = {m[i]:g}, {b_name} = {b:g}, {k_name} = {k:g} on axis {i}: the damping "
                    f"ratio b/(2*sqrt(m*k)) = {zeta:g} must be finite"
                )
            decay = _slowest_decay(b * dt / m[i], k * dt * dt / m[i])
            if not decay >= MIN_DECAY_PER_TICK:
                raise ParameterError(
                    f"m = {m[i]:g}, {b_name} = {b:g}, {k_name} = {k:g} on axis {i}: the slowest "
                    f"mode decays by {decay:.3g} per tick of {dt:g} s, less than "
                    f"{MIN_DECAY_PER_TICK:g}, so in float64 the filter would never return to rest"
                )


def _slowest_decay(beta: float, kappa: float) -> float:
    """-Re(s) of the slowest root of s^2 + beta*s + kappa (s = lambda*dt, beta, kappa > 0):
    the fraction by which that mode decays per tick."""
    disc = beta * beta - 4.0 * kappa
    if disc < 0.0:
        return 0.5 * beta
    return 2.0 * kappa / (beta + math.sqrt(disc))  # (beta - sqrt(disc))/2 without cancelling
