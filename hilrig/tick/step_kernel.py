"""The tick's arithmetic as one compiled kernel: newest samples in, joint targets and row out.

``tick_kernel`` does, in one numba call over preallocated arrays, what the loop used to do in a
hundred Python-level calls: tare and tool gravity (the compensator's bias and load) at the
measured pose, rotation of the wrist wrench into the base frame, the 9-axis controller step
(``hilrig.control.run_compiled`` on the controller's own arrays), the protective-stop test,
X_r = X_d + e, warm-started inverse kinematics (``hilrig.robot.kinematics``), the joint offsets,
the safety clamp (``clamp_kernels``); :func:`tick_entry` is the same call with its 25 arrays
passed by address (:mod:`hilrig.array_table`: one array unboxed a call, not 25).

Semantics are those of the reference path (pinocchio FK/IK, :class:`SafetyClamp`,
:class:`GravityCompensator`, ``AdmittanceController.step``), checked against it to 1e-12 in
``tests/tick/test_tick_kernel.py``: a tick is *fresh* when the sensor and the robot are, and the
compensated input is finite; the controller steps every tick, on the last fresh input otherwise;
stale input, a command fault or a protective stop makes the tick a hold (brake step).

Numba caches this kernel (``cache=True``) with the control kernel compiled into it; the cache
is keyed on the source of every module either compiles in (:mod:`hilrig.compiled`), so a change
to the control kernel alone recompiles the tick too.
"""

from __future__ import annotations

import inspect
import math

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import Layout, view1, view2, view3
from hilrig.compiled import njit
from hilrig.control import run_compiled
from hilrig.recording.schema import AXES
from hilrig.robot import JOINTS
from hilrig.robot.kinematics import fk_into, ik_into
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
)

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


TICK_ARGUMENTS = tuple(inspect.signature(tick_kernel.py_func).parameters)[:-1]  # the arrays' names
# (dtype, dimensions) of tick_kernel's arrays, in its order: tick_entry's table
TICK_LAYOUT: Layout = (
    *((np.float64, 1),) * 5,  # raw wrench, q, torque, extra input, desired position
    *((np.float64, 2),) * 2,  # desired rotation, compensation
    (np.float64, 3),  # frames
    *((np.float64, 2),) * 3,  # axes, joint limits, P
    (np.int64, 1),  # cfg
    (np.float64, 2),  # S
    (np.int64, 2),  # G
    (np.float64, 3),  # out
    (np.int8, 2),  # contact
    (np.float64, 1),  # offset
    *((np.float64, 2),) * 3,  # clamp limits, box, clamp state
    *((np.float64, 1),) * 2,  # options, work
    (np.float64, 2),  # IK work
    (np.float64, 3),  # poses
    (np.int64, 1),  # counters
)


@njit(cache=True)
def tick_entry(table: NDArray[np.int64], flags_in: int) -> int:
    """:func:`tick_kernel` on the arrays of ``table`` (an :class:`~hilrig.array_table.ArrayTable`
    of TICK_LAYOUT)."""
    f8, i8 = np.float64, np.int64
    return tick_kernel(
        view1(table, 0, f8),
        view1(table, 1, f8),
        view1(table, 2, f8),
        view1(table, 3, f8),
        view1(table, 4, f8),
        view2(table, 5, f8),
        view2(table, 6, f8),
        view3(table, 7, f8),
        view2(table, 8, f8),
        view2(table, 9, f8),
        view2(table, 10, f8),
        view1(table, 11, i8),
        view2(table, 12, f8),
        view2(table, 13, i8),
        view3(table, 14, f8),
        view2(table, 15, np.int8),
        view1(table, 16, f8),
        view2(table, 17, f8),
        view2(table, 18, f8),
        view2(table, 19, f8),
        view1(table, 20, f8),
        view1(table, 21, f8),
        view2(table, 22, f8),
        view3(table, 23, f8),
        view1(table, 24, i8),
        flags_in,
    )
