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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from hilrig.control import (
    AdmittanceController,
    KernelArrays,
    combine,
    make,
    preset,
    run_compiled,
)
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.rig.clamp_kernels import HOLDING, NON_FINITE, candidate, exceeds, finish
from hilrig.rig.records import AXES, JOINTS, TICK_DTYPE
from hilrig.rig.rings import Ring, RingSpec
from hilrig.rig.safety import SafetyClamp, SafetyConfig
from hilrig.rig.trajectory import make_trajectory
from hilrig.robot import RobotModel
from hilrig.robot.kinematics import CompiledChain, fk_into, ik_into, ik_work

# Bits of the kernel's input flags and result (besides the clamp's flags in the low byte).
SENSOR_OK, ROBOT_OK, COMMAND_OK = 1, 2, 4
FRESH, HELD, STOP_NOW = 1 << 8, 1 << 9, 1 << 10
# Entries of the int64 counters array.
TICK, STOPPED, HOLD_TICKS, IK_UNCONVERGED = range(4)
# Entries of the float64 options array.
FORCE_MAX, TORQUE_MAX, IK_TOL_POS, IK_TOL_ROT, IK_DAMPING, IK_MAX_STEP, DT = range(7)
IK_MAX_ITERATIONS = 2
IK_TOLERANCE = 1e-8  # m and rad: warm-started, one Gauss-Newton step a tick meets it

# Offsets into the ``work`` vector (float64).
W_FRESH, W_FORCE, W_WRENCH, W_MOMENT, W_GRAVITY_S = 0, 9, 18, 24, 27
W_Q_IK, W_TARGET, W_Q_CMD = 30, 36, 42
WORK_SIZE = 48


@njit(cache=True)
def tick_kernel(
    flags_in: int,
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
) -> int:
    """One tick; returns the clamp's flags | FRESH | HELD | STOP_NOW (see module constants).

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
    counters[TICK] += 1
    return result


@njit(cache=True)
def fill_tick_row(
    rows: NDArray[np.void],
    slot: int,
    work: NDArray[np.float64],
    results: NDArray[np.float64],
    contact: NDArray[np.int8],
    mass: NDArray[np.float64],
    position_d: NDArray[np.float64],
    orientation_d: NDArray[np.float64],
    timing: NDArray[np.int64],
) -> None:
    """Write the tick's row (TICK_DTYPE) into ``rows[slot]``.

    ``results`` is the controller's ``out`` (offset, rate, damping, stiffness rows of one tick);
    ``timing`` (7,): t_ns, tick, period_ns, compute_ns, lateness_ns, overruns, queue_drops.
    """
    row = rows[slot]
    row.t_ns = timing[0]
    row.tick = timing[1]
    row.period_ns = timing[2]
    row.compute_ns = timing[3]
    row.lateness_ns = timing[4]
    row.overruns = timing[5]
    row.queue_drops = timing[6]
    for i in range(AXES):
        f = work[W_FORCE + i]
        b = results[2, 0, i]
        k = results[3, 0, i]
        row.force[i] = f
        row.offset[i] = results[0, 0, i]
        row.offset_rate[i] = results[1, 0, i]
        row.damping[i] = b
        row.stiffness[i] = k
        row.chi[i] = math.tanh(f * f)
        row.zeta[i] = b / math.sqrt(mass[i] * k) * 0.5
        row.contact[i] = contact[0, i]
    for r in range(3):
        row.moment[r] = work[W_MOMENT + r]
        row.desired_position[r] = position_d[r]
    for r in range(4):
        row.desired_orientation[r] = orientation_d[r]
    for j in range(JOINTS):
        row.commanded_q[j] = work[W_Q_CMD + j]


@dataclass
class CompiledTick:
    """The kernel's arrays for one session, built from the same objects the reference path uses.

    The controller, clamp and compensator keep their own state arrays, which the kernel updates
    in place; ``q_ik`` starts at the measured start pose.
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

    @classmethod
    def build(
        cls,
        controller: AdmittanceController,
        model: RobotModel,
        clamp: SafetyClamp,
        compensator: GravityCompensator,
        q0_rad: NDArray[np.float64],
        dt_s: float,
    ) -> CompiledTick:
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
        counters = np.zeros(4, dtype=np.int64)
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
        """One tick (see :func:`tick_kernel`)."""
        k = self.arrays
        chain = self.chain
        limits, box, state = self.clamp_arrays
        result: int = tick_kernel(
            flags_in,
            raw_wrench,
            q_measured,
            torque_measured,
            extra_input,
            position_d,
            rotation_d,
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
        return result


def warm_up() -> None:
    """Load (or compile) the tick's kernels and run them once on a throwaway state built like a
    session's (read-only trajectory rotation, rows in a shared-memory ring: numba compiles per
    array type), so that no first-call cost lands on a session's first ticks."""
    model = RobotModel()
    q0 = np.asarray(HOME_Q_RAD, dtype=np.float64)
    controller = make("adaptive", combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6)))
    clamp = SafetyClamp(SafetyConfig(), model, q0)
    tick = CompiledTick.build(controller, model, clamp, GravityCompensator(), q0, 0.001)
    trajectory = make_trajectory("hold", model.fk(q0))
    position = np.zeros(3)
    trajectory.desired(0.0, position)
    zeros6 = np.zeros(6)
    flags = SENSOR_OK | ROBOT_OK | COMMAND_OK
    tick.run(flags, zeros6, q0, zeros6, np.zeros(AXES), position, trajectory.rotation)
    ring = Ring.create(RingSpec.unique("warm", TICK_DTYPE, 2))
    try:
        k = tick.arrays
        fill_tick_row(ring.rows, 0, tick.work, k.out, k.contact, k.mass, position,
                      trajectory.orientation, np.zeros(7, dtype=np.int64))  # fmt: skip
    finally:
        ring.unlink()
        ring.close()


__all__ = ["CompiledTick", "fill_tick_row", "tick_kernel", "warm_up"]
