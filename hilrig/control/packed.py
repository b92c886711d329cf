"""Parameters resolved, validated and packed into the compiled kernel's arrays.

``Packed.build`` is where every controller starts: a preset name, an ``AdmittanceParams`` or a
mapping becomes the kernel's parameter array P and int config cfg (row layout in axis.py),
refused with one ParameterError line when invalid or unstable.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hilrig.control import axis as K  # noqa: N812 - the kernel's notation (axis.py)
from hilrig.control.params import (
    AdmittanceParams,
    AxisBounds,
    BetaReading,
    ChiReading,
    Integrator,
    Law,
    from_mapping,
    parse_law,
    validate,
)
from hilrig.control.presets import preset
from hilrig.errors import NonFiniteForceError

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


@dataclass(frozen=True)
class Packed:
    """Validated parameters packed for the kernel (see axis.py for the row layout)."""

    law: Law
    params: AdmittanceParams
    axes: int
    dt: float
    P: NDArray[np.float64]
    cfg: NDArray[np.int64]
    bounds: AxisBounds

    @staticmethod
    def build(law: Law | str, params: ParamsLike, axes: int, dt: float) -> Packed:
        law = parse_law(law)
        resolved = resolve_params(params)
        found = validate(law, resolved, axes, dt)
        P = np.zeros((K.NP, axes))  # noqa: N806
        for row, name in ((K.M, "m"), (K.BD, "b_d"), (K.KD, "k_d"), (K.A1, "a1"), (K.A2, "a2")):
            P[row] = resolved.per_axis(name, axes)
        P[K.BETA] = resolved.per_axis("beta", axes)
        P[K.DELTA] = resolved.per_axis("delta", axes)
        P[K.BMIN] = found.b_min
        with np.errstate(over="ignore"):  # inf for extreme accepted parameters: no guard
            P[K.GROWTH] = np.exp(found.gamma * dt)
        P[K.TOL] = resolved.per_axis("settle_tol", axes)
        P[K.DT] = dt
        P[K.DTM] = dt / P[K.M]
        P[K.KX] = dt * dt / P[K.M]
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
        S = np.zeros((K.NS, self.axes))  # noqa: N806
        S[K.B] = self.P[K.BD]
        S[K.K] = self.P[K.KD]
        S[K.CB] = np.nan  # no b cached yet
        zoh = self.params.integrator is Integrator.ZOH
        for i in range(self.axes):
            K.discretise(self.P, S, i, S[K.B, i], S[K.K, i], zoh)
        return S, np.zeros((K.NG, self.axes), dtype=np.int64)


def refuse_nonfinite(force: NDArray[np.float64], tick_offset: int = 0) -> None:
    """Raise NonFiniteForceError naming the first NaN/inf of ``force`` (T, A), if any."""
    bad = ~np.isfinite(force)
    if bad.any():
        n, i = np.unravel_index(int(np.argmax(bad)), force.shape)
        raise NonFiniteForceError(
            f"force[{tick_offset + int(n)}, {int(i)}] is {force[n, i]}: non-finite force is "
            "refused and nothing from that tick on was integrated"
        )
