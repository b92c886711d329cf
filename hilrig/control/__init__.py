"""Admittance control (paper section 2): laws, integrator, contact state machine, guard.

Pure computation, no I/O. The public API::

    simulate(law, force, dt, params) -> SimResult      # a whole trace (T, A), from rest
    make(law, params, axes, dt) -> AdmittanceController  # .step(force_row) per tick

Both run one compiled kernel, so they give identical numbers. Compiled callers (the rig's tick)
call that kernel themselves: ``run_compiled(*controller.kernel_arrays()[:7])``.
"""

from hilrig.control.controller import (
    AdmittanceController,
    KernelArrays,
    SimResult,
    gains,
    make,
    resolve_params,
    simulate,
)
from hilrig.control.kernel import run as run_compiled
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

# The contact state codes (``SimResult.contact``) are the recording's; the kernel emits them.
from hilrig.recording.samples import ContactState

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
    "KernelArrays",
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
    "run_compiled",
    "simulate",
    "stability_report",
]
