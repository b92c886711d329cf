"""Admittance control (paper section 2): laws, integrator, contact state machine, guard.

Pure computation, no I/O. The public API::

    simulate(law, force, dt, params) -> SimResult      # a whole trace (T, A), from rest
    make(law, params, axes, dt) -> AdmittanceController  # .step(force_row) per tick

Both run one compiled kernel, so they give identical numbers.
"""

from hilrig.control.controller import (
    AdmittanceController,
    ContactState,
    SimResult,
    gains,
    make,
    resolve_params,
    simulate,
)
from hilrig.control.params import (
    AdmittanceParams,
    AxisBounds,
    BetaReading,
    ChiReading,
    Integrator,
    Law,
    bounds,
    combine,
)
from hilrig.control.presets import PAPER_DT_S, PRESETS, preset
from hilrig.control.stability import StabilityReport, stability_report
from hilrig.errors import NonFiniteForceError, ParameterError

__all__ = [
    "PAPER_DT_S",
    "PRESETS",
    "AdmittanceController",
    "AdmittanceParams",
    "AxisBounds",
    "BetaReading",
    "ChiReading",
    "ContactState",
    "Integrator",
    "Law",
    "NonFiniteForceError",
    "ParameterError",
    "SimResult",
    "StabilityReport",
    "bounds",
    "combine",
    "gains",
    "make",
    "preset",
    "resolve_params",
    "simulate",
    "stability_report",
]
