"""The per-tick controller: ``make`` builds it for the live loop; ``run_into`` runs blocks.

``step`` and ``run_into`` call the same compiled kernel (``kernel.run``) on the same packed
state, and :func:`hilrig.control.simulate` is ``run_into`` on a controller at rest, so a session
replayed offline reproduces the offsets its live ``step`` calls commanded, bit for bit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hilrig.compiled import njit
from hilrig.control import axis as K
from hilrig.control.kernel import run
from hilrig.control.packed import Packed, ParamsLike, refuse_nonfinite, resolve_params
from hilrig.control.params import AdmittanceParams, AxisBounds, Law
from hilrig.errors import ParameterError

#: The quantities ``run_into`` writes along the first axis of its ``out``, in this order.
OUTPUTS: tuple[str, ...] = K.OUTPUTS
_RUN_INTO_DTYPES = (np.dtype(np.float64), np.dtype(np.float64), np.dtype(np.int8))


def damping_ratio(
    damping: NDArray[np.float64],
    stiffness: NDArray[np.float64],
    mass: NDArray[np.float64],
    out: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """zeta = b / (2 sqrt(m k)) elementwise (broadcasting), written into ``out`` when given.

    One formula in one order of operations, so every zeta hilrig reports is bit-equal.
    """
    zeta: NDArray[np.float64] = np.multiply(stiffness, mass, out=out)
    np.sqrt(zeta, out=zeta)
    np.multiply(zeta, 2.0, out=zeta)
    np.divide(damping, zeta, out=zeta)
    return zeta


@njit(cache=True, error_model="numpy")
def damping_ratio_rows(
    damping: NDArray[np.float64],
    stiffness: NDArray[np.float64],
    mass: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled (tests/control/test_control_damping_ratio.py)
    """:func:`damping_ratio` of (A, T) rows, one mass per row (``mass`` (A,)), into ``out``
    (A, T) in one compiled pass instead of four: the same operations in the same order, so the
    same bits (IEEE division and square root; NaN or inf where NumPy gives them)."""
    for a in range(out.shape[0]):
        m = mass[a]
        for t in range(out.shape[1]):
            out[a, t] = damping[a, t] / (math.sqrt(stiffness[a, t] * m) * 2.0)


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
    ``run_into`` advances it over a block of ticks into arrays the caller provides.
    """

    def __init__(self, packed: Packed) -> None:
        self._packed = packed
        self._force = np.zeros((1, packed.axes))
        self._out = np.zeros((len(OUTPUTS), 1, packed.axes))
        self._contact = np.zeros((1, packed.axes), dtype=np.int8)
        self._S, self._G = packed.initial_state()
        self._ticks = 0
        # Typed views into the buffers the kernel writes; step() returns _offset itself.
        self._offset: NDArray[np.float64] = self._out[K.OUT_OFFSET, 0]
        self._velocity: NDArray[np.float64] = self._out[K.OUT_VELOCITY, 0]
        self._damping: NDArray[np.float64] = self._out[K.OUT_DAMPING, 0]
        self._stiffness: NDArray[np.float64] = self._out[K.OUT_STIFFNESS, 0]
        self._m: NDArray[np.float64] = packed.P[K.M]
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

    def at_rest(self) -> AdmittanceController:
        """A new controller with this one's law, parameters and dt, at rest."""
        return AdmittanceController(self._packed)

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
        code = run(
            self._force,
            self._packed.P,
            self._packed.cfg,
            self._S,
            self._G,
            self._out,
            self._contact,
        )
        if code >= 0:
            refuse_nonfinite(self._force, self._ticks)
        self._ticks += 1
        return self._offset

    def run_into(
        self,
        force: NDArray[np.float64],
        out: NDArray[np.float64],
        contact: NDArray[np.int8],
    ) -> None:
        """Advance one tick per row of ``force`` (T, axes), as T calls of ``step`` would.

        Tick n's quantities go to ``out[:, n]`` ((len(OUTPUTS), T, axes) float64, in
        :data:`OUTPUTS` order) and its ContactState codes to ``contact[n]`` ((T, axes) int8);
        any strides will do, so these may be views of the caller's columns. Afterwards the
        step properties (``offset`` ...) are those of the last tick. Raises ParameterError for
        arrays of the wrong shape or type, NonFiniteForceError at the first NaN/inf force (the
        ticks before it are integrated, nothing from it on).
        """
        ticks, axes = force.shape[0] if force.ndim == 2 else -1, self._packed.axes
        shapes = ((ticks, axes), (len(OUTPUTS), ticks, axes), (ticks, axes))
        got = (force.shape, out.shape, contact.shape), (force.dtype, out.dtype, contact.dtype)
        if got != (shapes, _RUN_INTO_DTYPES):
            raise ParameterError(
                f"run_into takes force (T, {axes}) and out ({len(OUTPUTS)}, T, {axes}) float64, "
                f"contact (T, {axes}) int8; got {force.shape} {force.dtype}, "
                f"{out.shape} {out.dtype}, {contact.shape} {contact.dtype}"
            )
        p = self._packed
        code = run(force, p.P, p.cfg, self._S, self._G, out, contact)
        done = ticks if code < 0 else code // axes
        if done > 0:
            self._out[:, 0] = out[:, done - 1]
            self._contact[0] = contact[done - 1]
        first = self._ticks
        self._ticks += done
        if code >= 0:
            refuse_nonfinite(force, first)

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
    def mass(self) -> NDArray[np.float64]:
        """m of each axis (kg, or kg*m^2 on joints)."""
        return self._m

    @property
    def zeta(self) -> NDArray[np.float64]:
        """Damping ratio b/(2*sqrt(m*k)) of the last step (allocates: not for the tick)."""
        return damping_ratio(self._damping, self._stiffness, self._m)

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
