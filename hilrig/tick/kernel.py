"""The compiled tick over one session's arrays: :class:`CompiledTick` and its inputs.

:class:`CompiledTick` builds the arrays :func:`~hilrig.tick.step_kernel.tick_kernel` works on
from the same objects the reference path uses (controller, clamp, compensator, robot model) and
binds the kernel to them by address (:func:`~hilrig.tick.step_kernel.tick_entry`, an
:class:`~hilrig.array_table.ArrayTable`): :meth:`CompiledTick.step` is one compiled call with
one array to unbox. :meth:`CompiledTick.loop_step` (the live loop's tick, judging its inputs'
freshness too) and :meth:`CompiledTick.row_writer` (the tick's recorder row) bind the same way.
The kernel's flags and counters are re-exported here for the loop and the replay.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import ArrayTable
from hilrig.control import AdmittanceController, KernelArrays
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.recording.schema import AXES
from hilrig.robot import JOINTS, RobotModel
from hilrig.robot.kinematics import CompiledChain, ik_work
from hilrig.tick.loop_step import LOOP_LAYOUT, loop_entry
from hilrig.tick.row import ROW_LAYOUT, W_FORCE, W_Q_CMD, W_Q_IK, WORK_SIZE, put_tick_row
from hilrig.tick.safety import SafetyClamp
from hilrig.tick.step_kernel import (
    COMMAND_OK,
    CONTACT_CHANGED,
    DT,
    FORCE_MAX,
    FRESH,
    HELD,
    HOLD_TICKS,
    IK_DAMPING,
    IK_MAX_STEP,
    IK_TOL_POS,
    IK_TOL_ROT,
    IK_TOLERANCE,
    ROBOT_OK,
    SENSOR_OK,
    STOP_NOW,
    STOPPED,
    TICK_ARGUMENTS,
    TICK_LAYOUT,
    TORQUE_MAX,
    tick_entry,
)


@dataclass
class TickInputs:
    """The per-tick inputs the loop writes in place before each :meth:`CompiledTick.step`: the
    raw wrist wrench (6,) in the sensor frame, measured joints (6,) rad and torques (6,) N*m, an
    extra input (9,) added to the controller's (a virtual collision), and the desired TCP pose:
    position (3,) m, rotation (3, 3) and orientation (4,) quaternion (w, x, y, z), base frame."""

    raw_wrench: NDArray[np.float64] = field(default_factory=lambda: np.zeros(6))
    q_measured: NDArray[np.float64] = field(default_factory=lambda: np.zeros(JOINTS))
    torque_measured: NDArray[np.float64] = field(default_factory=lambda: np.zeros(JOINTS))
    extra: NDArray[np.float64] = field(default_factory=lambda: np.zeros(AXES))
    position_d: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    rotation_d: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    orientation_d: NDArray[np.float64] = field(default_factory=lambda: np.array([1.0, 0, 0, 0]))


@dataclass
class CompiledTick:
    """The kernel's arrays for one session, built from the same objects the reference path uses.

    The controller, clamp and compensator keep their own state arrays, which the kernel updates
    in place; ``q_ik`` starts at the measured start pose. The loop fills :attr:`inputs` and calls
    :meth:`step` (the kernel bound to these arrays by address: no per-call dispatch, one array
    unboxed; :mod:`hilrig.array_table`); :meth:`run` copies given inputs first.
    """

    arrays: KernelArrays
    chain: CompiledChain
    clamp: SafetyClamp
    clamp_arrays: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
    compensation: NDArray[np.float64]
    options: NDArray[np.float64]
    work: NDArray[np.float64]
    ik_work: NDArray[np.float64]
    poses: NDArray[np.float64]
    counters: NDArray[np.int64]
    inputs: TickInputs = field(default_factory=TickInputs)
    step: Callable[[int], int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        table = ArrayTable(self.kernel_args(), TICK_ARGUMENTS)
        self.step = table.bind(tick_entry, TICK_LAYOUT, last=(0,))

    def kernel_args(self) -> tuple[NDArray[np.generic], ...]:
        """The arrays :func:`tick_kernel` takes, in order (all but the flags)."""
        i, k, chain = self.inputs, self.arrays, self.chain
        limits, box, state = self.clamp_arrays
        return (
            i.raw_wrench,
            i.q_measured,
            i.torque_measured,
            i.extra,
            i.position_d,
            i.rotation_d,
            self.compensation,
            chain.frames,
            chain.axes,
            chain.limits,
            k.P,
            k.cfg,
            k.S,
            k.G,
            k.out,
            k.contact,
            k.offset,
            limits,
            box,
            state,
            self.options,
            self.work,
            self.ik_work,
            self.poses,
            self.counters,
        )

    @classmethod
    def build(
        cls,
        controller: AdmittanceController,
        model: RobotModel,
        clamp: SafetyClamp,
        compensator: GravityCompensator,
        q0_rad: NDArray[np.float64],
        dt_s: float,
        inputs: TickInputs | None = None,
    ) -> CompiledTick:
        """The kernel's arrays for these parts; ``inputs`` (default: zeros) are the arrays the
        kernel reads, which may be views a driver keeps current (the loop's)."""
        compensation = np.zeros((6, 5))
        compensation[:, 0] = compensator.bias_in_sensor
        compensation[:, 1:4] = compensator.load.wrench_map()
        compensation[:3, 4] = compensator.gravity_in_base
        config = clamp.config
        options = np.zeros(7)
        options[FORCE_MAX] = config.protective_force_n
        options[TORQUE_MAX] = config.protective_torque_nm
        options[IK_TOL_POS] = options[IK_TOL_ROT] = IK_TOLERANCE
        options[IK_DAMPING] = 1e-4
        options[IK_MAX_STEP] = 0.5
        options[DT] = dt_s
        work = np.zeros(WORK_SIZE)
        work[W_Q_IK : W_Q_IK + JOINTS] = q0_rad
        work[W_Q_CMD : W_Q_CMD + JOINTS] = q0_rad
        poses = np.tile(np.eye(4), (3, 1, 1))
        counters = np.zeros(6, dtype=np.int64)
        chain = CompiledChain.from_model(model)
        arrays = controller.kernel_arrays()
        return cls(
            arrays,
            chain,
            clamp,
            clamp.kernel_arrays(),
            compensation,
            options,
            work,
            ik_work(),
            poses,
            counters,
            TickInputs() if inputs is None else inputs,
        )

    @property
    def q_cmd(self) -> NDArray[np.float64]:
        """The joints commanded by the last tick (6,), rad (a view)."""
        return self.work[W_Q_CMD : W_Q_CMD + JOINTS]

    @property
    def force(self) -> NDArray[np.float64]:
        """The controller input of the last tick (9,), N and N*m (a view)."""
        return self.work[W_FORCE : W_FORCE + AXES]

    @property
    def stopped(self) -> bool:
        return bool(self.counters[STOPPED])

    def run(
        self,
        flags_in: int,
        raw_wrench: NDArray[np.float64],
        q_measured: NDArray[np.float64],
        torque_measured: NDArray[np.float64],
        extra_input: NDArray[np.float64],
        position_d: NDArray[np.float64],
        rotation_d: NDArray[np.float64],
    ) -> int:
        """One tick on these inputs (copied into :attr:`inputs`; see :func:`tick_kernel`)."""
        i = self.inputs
        i.raw_wrench[:] = raw_wrench
        i.q_measured[:] = q_measured
        i.torque_measured[:] = torque_measured
        i.extra[:] = extra_input
        i.position_d[:] = position_d
        i.rotation_d[:] = rotation_d
        return self.step(flags_in)

    def loop_step(
        self,
        newest_sample: NDArray[np.void],
        newest_state: NDArray[np.void],
        words: NDArray[np.int64],
    ) -> Callable[[int], int]:
        """``step(start_ns) -> result``: the live loop's tick (:func:`loop_entry`, by address),
        judging freshness from the drivers' ``newest_sample`` and ``newest_state`` rows (kept
        current in place) and the loop's ``words`` (:func:`~hilrig.tick.loop_step.loop_words`)."""
        arrays = (*self.kernel_args(), newest_sample, newest_state, words)
        return ArrayTable(arrays).bind(loop_entry, LOOP_LAYOUT, last=(0,))

    def row_writer(
        self,
        rows: NDArray[np.void],
        header: NDArray[np.int64],
        drops_from: tuple[NDArray[np.int64], ...],
    ) -> Callable[..., bool]:
        """Puts this tick's row into the ring of ``rows`` and ``header`` when called with the
        row's six timing ints (:func:`put_tick_row`, its arrays by address; ``drops_from``: the
        headers whose drops the row's ``queue_drops`` adds up)."""
        k, i = self.arrays, self.inputs
        arrays = (rows, header, self.work, k.out, k.contact, k.mass, i.position_d, i.orientation_d)
        layout = ROW_LAYOUT + ((np.int64, 1),) * len(drops_from)
        return ArrayTable((*arrays, *drops_from)).bind(put_tick_row, layout, last=(0,) * 6)


__all__ = [
    "COMMAND_OK",
    "CONTACT_CHANGED",
    "FRESH",
    "HELD",
    "HOLD_TICKS",
    "ROBOT_OK",
    "SENSOR_OK",
    "STOPPED",
    "STOP_NOW",
    "CompiledTick",
    "TickInputs",
]
