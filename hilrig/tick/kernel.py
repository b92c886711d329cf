"""The tick's arithmetic as one compiled kernel: newest samples in, joint targets and row out.

``tick_kernel`` does, in one numba call over preallocated arrays, what the loop used to do in a
hundred Python-level calls: tare and tool gravity (the compensator's bias and load) at the
measured pose, rotation of the wrist wrench into the base frame, the 9-axis controller step
(``hilrig.control.run_compiled`` on the controller's own arrays), the protective-stop test,
X_r = X_d + e, warm-started inverse kinematics (``hilrig.robot.kinematics``), the joint offsets,
the safety clamp (``clamp_kernels``) and the tick row in the recorder's ring slot.

Semantics are those of the reference path (pinocchio FK/IK, :class:`SafetyClamp`,
:class:`GravityCompensator`, ``AdmittanceController.step``), checked against it to 1e-12 in
``tests/rig/test_tick_kernel.py``: a tick is *fresh* when the sensor and the robot are, and the
compensated input is finite; the controller steps every tick, on the last fresh input otherwise;
stale input, a command fault or a protective stop makes the tick a hold (brake step).

Numba caches this kernel (``cache=True``) with the control kernel compiled into it; the cache
is keyed on the source of every module either compiles in (:mod:`hilrig.compiled`), so a change
to the control kernel alone recompiles the tick too.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.control import (
    AdmittanceController,
    KernelArrays,
    run_compiled,
)
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.recording.schema import AXES
from hilrig.robot import JOINTS, RobotModel
from hilrig.robot.kinematics import CompiledChain, fk_into, ik_into, ik_work
from hilrig.tick.clamp_kernels import HOLDING, NON_FINITE, candidate, exceeds, finish
from hilrig.tick.row import (
    W_FORCE,
    W_FRESH,
    W_GRAVITY_S,
    W_MOMENT,
    W_Q_CMD,
    W_Q_IK,
    W_TARGET,
    W_WRENCH,
    WORK_SIZE,
    put_tick_row,
)
from hilrig.tick.safety import SafetyClamp
from hilrig.timing import bound_kernel

# Bits of the kernel's input flags and result (besides the clamp's flags in the low byte).
SENSOR_OK, ROBOT_OK, COMMAND_OK = 1, 2, 4
FRESH, HELD, STOP_NOW, CONTACT_CHANGED = 1 << 8, 1 << 9, 1 << 10, 1 << 11
# Entries of the int64 counters array: counts, and the contact codes of the last tick's axis
# groups (end effector: axis 0, joints: axis 3; hilrig.rig.events.GROUPS).
TICK, STOPPED, HOLD_TICKS, IK_UNCONVERGED, CONTACT_EE, CONTACT_JOINTS = range(6)
# Entries of the float64 options array.
FORCE_MAX, TORQUE_MAX, IK_TOL_POS, IK_TOL_ROT, IK_DAMPING, IK_MAX_STEP, DT = range(7)
IK_MAX_ITERATIONS = 2
IK_TOLERANCE = 1e-8  # m and rad: warm-started, one Gauss-Newton step a tick meets it


@njit(cache=True)
def tick_kernel(
    raw_wrench: NDArray[np.float64],
    q_measured: NDArray[np.float64],
    torque_measured: NDArray[np.float64],
    extra_input: NDArray[np.float64],
    position_d: NDArray[np.float64],
    rotation_d: NDArray[np.float64],
    compensation: NDArray[np.float64],
    frames: NDArray[np.float64],
    axes: NDArray[np.float64],
    joint_limits: NDArray[np.float64],
    P: NDArray[np.float64],  # noqa: N803 - the controller kernel's names
    cfg: NDArray[np.int64],
    S: NDArray[np.float64],  # noqa: N803
    G: NDArray[np.int64],  # noqa: N803
    out: NDArray[np.float64],
    contact: NDArray[np.int8],
    offset: NDArray[np.float64],
    clamp_limits: NDArray[np.float64],
    box: NDArray[np.float64],
    clamp_state: NDArray[np.float64],
    options: NDArray[np.float64],
    work: NDArray[np.float64],
    ik_work: NDArray[np.float64],
    poses: NDArray[np.float64],
    counters: NDArray[np.int64],
    flags_in: int,
) -> int:
    """One tick; returns the clamp's flags | FRESH | HELD | STOP_NOW | CONTACT_CHANGED (see the
    module constants).

    ``compensation`` (6, 5): per wrench axis the bias, then the tool's wrench map (6, 3) in
    columns 1-3, and in column 4 rows 0-2 gravity in the base frame (m/s^2). ``work`` (48,)
    holds the tick's vectors (see ``W_*``), ``ik_work`` is the IK's scratch, ``poses``
    (3, 4, 4) the measured TCP pose, the reference X_r and the clamp candidate's pose.
    ``out``/``contact`` are the controller's result arrays and ``offset`` (9,) the view of its
    offsets; the force it integrates is ``work[W_FORCE:W_FORCE + 9]``.
    """
    pose_m, x_r, pose_c = poses[0], poses[1], poses[2]
    force = work[W_FORCE : W_FORCE + AXES]
    fresh = (flags_in & SENSOR_OK) != 0 and (flags_in & ROBOT_OK) != 0
    result = 0
    if fresh:
        fk_into(frames, axes, q_measured, pose_m)
        # tool gravity in the sensor frame: R^T g, then the load's wrench map
        for k in range(3):
            acc = 0.0
            for r in range(3):
                acc += compensation[r, 4] * pose_m[r, k]
            work[W_GRAVITY_S + k] = acc
        finite = True
        for a in range(6):
            tool = 0.0
            for k in range(3):
                tool += compensation[a, 1 + k] * work[W_GRAVITY_S + k]
            w = (raw_wrench[a] - compensation[a, 0]) - tool
            work[W_WRENCH + a] = w
            finite &= math.isfinite(w)
        for r in range(3):
            acc = 0.0
            for k in range(3):
                acc += pose_m[r, k] * work[W_WRENCH + k]
            work[W_FRESH + r] = acc + extra_input[r]
        for j in range(JOINTS):
            work[W_FRESH + 3 + j] = torque_measured[j] + extra_input[3 + j]
        for i in range(AXES):
            finite &= math.isfinite(work[W_FRESH + i])
        fresh = finite
    if fresh:
        result |= FRESH
        for i in range(AXES):
            force[i] = work[W_FRESH + i]
        for r in range(3):
            acc = 0.0
            for k in range(3):
                acc += pose_m[r, k] * work[W_WRENCH + 3 + k]
            work[W_MOMENT + r] = acc
        if counters[STOPPED] == 0 and exceeds(
            force[:3], force[3:], options[FORCE_MAX], options[TORQUE_MAX]
        ):
            counters[STOPPED] = 1
            result |= STOP_NOW
    run_compiled(force.reshape((1, AXES)), P, cfg, S, G, out, contact)
    q_cmd = work[W_Q_CMD : W_Q_CMD + JOINTS]
    dt = options[DT]
    if not fresh or (flags_in & COMMAND_OK) == 0 or counters[STOPPED] != 0:
        finish(pose_c, box, clamp_limits, clamp_state, dt, q_cmd, True)
        counters[HOLD_TICKS] += 1
        result |= HOLDING | HELD
    else:
        for r in range(3):
            x_r[r, 3] = position_d[r] + offset[r]
            for k in range(3):
                x_r[r, k] = rotation_d[r, k]
        q_ik = work[W_Q_IK : W_Q_IK + JOINTS]
        iterations = ik_into(
            frames,
            axes,
            joint_limits,
            x_r,
            q_ik,
            IK_MAX_ITERATIONS,
            options[IK_TOL_POS],
            options[IK_TOL_ROT],
            options[IK_DAMPING],
            options[IK_MAX_STEP],
            ik_work,
        )
        if iterations < 0:
            counters[IK_UNCONVERGED] += 1
        target = work[W_TARGET : W_TARGET + JOINTS]
        for j in range(JOINTS):
            target[j] = q_ik[j] + offset[3 + j]
        flags = candidate(target, clamp_limits, clamp_state, dt)
        if flags & NON_FINITE:
            finish(pose_c, box, clamp_limits, clamp_state, dt, q_cmd, True)
            flags = NON_FINITE | HOLDING
        else:
            fk_into(frames, axes, clamp_state[3], pose_c)  # CAND_Q row
            braked = finish(pose_c, box, clamp_limits, clamp_state, dt, q_cmd, False)
            if braked:
                flags = braked
        result |= flags
    if contact[0, 0] != counters[CONTACT_EE] or contact[0, 3] != counters[CONTACT_JOINTS]:
        counters[CONTACT_EE] = contact[0, 0]
        counters[CONTACT_JOINTS] = contact[0, 3]
        result |= CONTACT_CHANGED
    counters[TICK] += 1
    return result


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
    :meth:`step` (the kernel bound to these arrays: no per-call dispatch, see
    :func:`hilrig.timing.bound_kernel`); :meth:`run` copies given inputs first.
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
        self.step = bound_kernel(tick_kernel, *self.kernel_args(), last=(0,))

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

    def row_writer(
        self,
        rows: NDArray[np.void],
        header: NDArray[np.int64],
        drops_from: tuple[NDArray[np.int64], ...],
    ) -> Callable[..., bool]:
        """Puts this tick's row into the ring of ``rows`` and ``header`` when called with the
        row's six timing ints and the drops counted elsewhere (bound :func:`put_tick_row`;
        ``drops_from``: the headers whose drops the row's ``queue_drops`` adds up)."""
        k, i = self.arrays, self.inputs
        return bound_kernel(
            put_tick_row,
            rows,
            header,
            drops_from,
            self.work,
            k.out,
            k.contact,
            k.mass,
            i.position_d,
            i.orientation_d,
            last=(0,) * 7,
        )


__all__ = ["CompiledTick", "TickInputs", "put_tick_row", "tick_kernel"]
