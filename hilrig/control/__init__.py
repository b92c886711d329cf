"""Admittance control (paper section 2): laws, integrator, contact state machine, guard.

Pure computation, no I/O. The public API::

    simulate(law, force, dt, params) -> SimResult      # a whole trace (T, A), from rest
    make(law, params, axes, dt) -> AdmittanceController  # .step(force_row) per tick
    controller.run_into(force, out, contact)            # a block of ticks into your arrays
    damping_ratio(damping, stiffness, mass, out=None)   # zeta, bit-equal to every zeta here
    damping_ratio_rows(damping, stiffness, mass, out)   # the same over (A, T) rows, compiled
    release_memory()                                    # the blocks dropped results left (pool.py)

All of them run one compiled kernel, so they give identical numbers. ``run_into`` writes the
quantities named by ``OUTPUTS``, in that order. Compiled callers (the rig's tick) call that
kernel themselves: ``run_compiled(*controller.kernel_arrays()[:7])``.
"""

from hilrig.control.controller import (
    OUTPUTS,
    AdmittanceController,
    KernelArrays,
    damping_ratio,
    damping_ratio_rows,
    make,
)
from hilrig.control.kernel import run as run_compiled
from hilrig.control.packed import ParamsLike, resolve_params
from hilrig.control.params import (
    AdmittanceParams,
    AxisBounds,
    BetaReading,
    ChiReading,
    Integrator,
    Law,
    bounds,
    combine,
    parse_law,
)
from hilrig.control.pool import release_memory
from hilrig.control.presets import PAPER_DT_S, PRESETS, preset
from hilrig.control.stability import StabilityReport, stability_report
from hilrig.control.traces import SimResult, gains, simulate
from hilrig.errors import NonFiniteForceError, ParameterError

# The contact state codes (``SimResult.contact``) are the recording's; the kernel emits them.
from hilrig.recording.samples import ContactState

__all__ = [
    "OUTPUTS",
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
    "ParamsLike",
    "SimResult",
    "StabilityReport",
    "bounds",
    "combine",
    "damping_ratio",
    "damping_ratio_rows",
    "gains",
    "make",
    "parse_law",
    "preset",
    "release_memory",
    "resolve_params",
    "run_compiled",
    "simulate",
    "stability_report",
]
