"""Whole traces: ``simulate`` a force trace from rest, ``gains`` of the bare law.

``simulate`` runs a controller at rest through :meth:`AdmittanceController.run_into`, the same
kernel the live ``step`` calls, so its numbers are the live loop's. Its outputs are views of one
block, which goes back to ``pool`` for the next call when the last of them is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hilrig.control import axis as K  # noqa: N812 - the kernel's notation (axis.py)
from hilrig.control import pool
from hilrig.control.controller import OUTPUTS, AdmittanceController, damping_ratio
from hilrig.control.packed import Packed, ParamsLike, refuse_nonfinite
from hilrig.control.params import AdmittanceParams, Law
from hilrig.errors import ParameterError


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
        return damping_ratio(self.damping, self.stiffness, m)

    @property
    def omega_n(self) -> NDArray[np.float64]:
        """Undamped natural frequency sqrt(k/m) per tick and axis, rad/s."""
        m = self.params.per_axis("m", self.offset.shape[1])
        return np.sqrt(self.stiffness / m)


def _trace(force: ArrayLike) -> NDArray[np.float64]:
    """``force`` as a C-contiguous float64 (T, A) array ((T,) is one axis)."""
    trace = np.ascontiguousarray(force, dtype=np.float64)
    if trace.ndim == 1:
        trace = trace[:, None]
    if trace.ndim != 2:
        raise ParameterError(f"force must be (T, axes), got shape {trace.shape}")
    return trace


def simulate(
    law: Law | str | AdmittanceController,
    force: ArrayLike,
    dt: float | None = None,
    params: ParamsLike | None = None,
) -> SimResult:
    """Run a whole force trace (T, A) (or (T,) for one axis) through a controller from rest.

    ``law`` is a law name or a controller (whose law, params and dt are used; it is not
    modified). Raises NonFiniteForceError naming the first NaN/inf of force (found by the
    kernel as it goes, so a finite trace is read once), ParameterError for invalid or unstable
    parameters. The result's arrays share one block: once all of them are dropped, the next
    call reuses it (``release_memory`` gives such blocks back to the system).
    """
    trace = _trace(force)
    if isinstance(law, AdmittanceController):
        if params is not None or (dt is not None and dt != law.dt):
            raise ParameterError("pass either a controller or law/params/dt, not both")
        if law.axes != trace.shape[1]:
            raise ParameterError(f"controller has {law.axes} axes, force has {trace.shape[1]}")
        controller = law.at_rest()
    else:
        if dt is None or params is None:
            raise ParameterError("dt and params are required with a law name")
        controller = AdmittanceController(Packed.build(law, params, trace.shape[1], dt))
    T, A = trace.shape  # noqa: N806 - kernel.py's notation
    out_bytes = len(OUTPUTS) * T * A * 8
    block = pool.take(out_bytes + T * A)  # the outputs, then contact: one block (pool.py)
    out = block[:out_bytes].view(np.float64).reshape(len(OUTPUTS), T, A)
    contact = block[out_bytes:].view(np.int8).reshape(T, A)
    controller.run_into(trace, out, contact)
    columns = dict(zip(OUTPUTS, out, strict=True))
    return SimResult(controller.law, controller.params, controller.dt, contact=contact, **columns)


def gains(
    law: Law | str, force: ArrayLike, params: ParamsLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The bare law's damping and stiffness for each row of force (T, A), no state machine."""
    trace = _trace(force)
    packed = Packed.build(law, params, trace.shape[1], 1e-3)
    refuse_nonfinite(trace)
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
