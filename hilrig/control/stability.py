"""Stability monitor: natural frequency and damping ratio over the law's parameter range.

A fixed-parameter axis is stable iff m, b, k > 0; the paper's "0 < zeta < 1" is not a stability
condition (its own collision parameters give zeta > 1), so zeta is reported, never enforced.
Parameters that cannot be stable are refused by ``params.validate`` before any motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.control.packed import ParamsLike, resolve_params
from hilrig.control.params import Law, parse_law, validate


@dataclass(frozen=True)
class StabilityReport:
    """Per-axis ranges (arrays of length axes): omega_n in rad/s, zeta dimensionless, gamma 1/s."""

    omega_n_min: NDArray[np.float64]
    omega_n_max: NDArray[np.float64]
    zeta_min: NDArray[np.float64]
    zeta_max: NDArray[np.float64]
    b_min: NDArray[np.float64]
    k_min: NDArray[np.float64]
    k_max: NDArray[np.float64]
    gamma: NDArray[np.float64]
    gamma_bound: NDArray[np.float64]


def stability_report(law: Law | str, params: ParamsLike, axes: int, dt: float) -> StabilityReport:
    """Validate (raising ParameterError if unstable) and report the law's stability ranges."""
    resolved = resolve_params(params)
    found = validate(parse_law(law), resolved, axes, dt)
    m = resolved.per_axis("m", axes)
    # zeta = b/(2*sqrt(m*k)) is smallest at (b_min, k_max) and largest at (b_max, k_min).
    return StabilityReport(
        omega_n_min=np.sqrt(found.k_min / m),
        omega_n_max=np.sqrt(found.k_max / m),
        zeta_min=found.b_min / (2.0 * np.sqrt(m * found.k_max)),
        zeta_max=found.b_max / (2.0 * np.sqrt(m * found.k_min)),
        b_min=found.b_min,
        k_min=found.k_min,
        k_max=found.k_max,
        gamma=found.gamma,
        gamma_bound=found.gamma_bound,
    )
