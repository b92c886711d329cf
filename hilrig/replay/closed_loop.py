"""Closed-loop re-simulation: a controller, the arm's response and the fitted contacts together,
tick by tick, through the live loop's own compiled tick (:mod:`hilrig.tick.kernel`).

Per recorded tick ``k`` (at the recorded tick times, so the loop's timing is the recording's):

1. the arm's servos (:func:`hilrig.world.response.advance`) are integrated up to ``t_k``,
   following the joints commanded ``delay_s`` earlier;
2. the controller's input is the recorded one plus, within a collision (from its first tick to
   the next collision's), the change the robot's different motion makes to the contact's push:
   ``F = F_rec + u (f(h - y_sim, ...) - f(h - y_rec, ...))``, ``f`` the fitted mechanics,
   ``h`` the body's fitted surface, ``y`` the contact point's travel along ``u`` (simulated:
   forward kinematics of the servos; recorded: of the measured joints). With the recorded
   motion the input is the recorded one exactly, so whatever the model does not explain
   (sensor noise, other axes, the joints' torques) is kept as recorded; a force source's
   collision is played as recorded;
3. the tick kernel runs on it as live (controller, protective stop, X_r = X_d + e, IK, clamp),
   with the link flags the live tick had (``link_flags``: a recorded hold holds here too,
   :mod:`hilrig.replay.recorded_holds`); its commanded joints go to the servos.

The compensation is zero and the input enters as the tick's extra input: the recorded input is
already compensated and in the base frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.robot.kinematics import fk_into
from hilrig.tick.kernel import CompiledTick
from hilrig.tick.row import W_Q_CMD
from hilrig.tick.step_kernel import tick_kernel
from hilrig.world.contact import HUNT_CROSSLEY_N, Mechanics
from hilrig.world.response import advance

# Columns of the packed collisions array (float64, one row per collision).
START, STOP, MECH, U, STIFFNESS, DAMPING, T_FULL, T_BACK, H_MAX, V_IN, V_OUT = (
    0, 1, 2, 3, 6, 7, 8, 9, 10, 11, 12)  # fmt: skip
REFERENCE, POINT = 13, 16
COLLISION_COLUMNS = 19
RATE_SPAN_S = 0.00095  # the shortest span a penetration rate is taken over (a 1 kHz tick)
MECHANICS_CODE = {Mechanics.SPRING_DAMPER: 0, Mechanics.HUNT_CROSSLEY: 1, Mechanics.FORCE_SOURCE: 2}

Array = NDArray[np.float64]


@njit(cache=True)
def push_n(mechanics: int, stiffness: float, damping: float, p_m: float, rate_m_s: float) -> float:
    """The body's push (N, >= 0) at penetration ``p_m`` and its rate (``ContactModel.force``)."""
    if p_m <= 0.0:
        return 0.0
    if mechanics == 0:
        push = stiffness * p_m + damping * rate_m_s
    else:
        push = stiffness * p_m**HUNT_CROSSLEY_N * (1.0 + damping * rate_m_s)
    return max(push, 0.0)


@njit(cache=True)
def surface_m(row: Array, t_s: float) -> float:
    """Where the body's surface is along ``u`` at ``t_s`` (``SurfaceMotion.at``), m."""
    if t_s < row[T_FULL]:
        return float(row[H_MAX] - row[V_IN] * (row[T_FULL] - t_s))
    if t_s > row[T_BACK]:
        return float(row[H_MAX] - row[V_OUT] * (t_s - row[T_BACK]))
    return float(row[H_MAX])


@njit(cache=True)
def _travel_m(row: Array, point: Array) -> float:
    acc = 0.0
    for r in range(3):
        acc += (point[r] - row[REFERENCE + r]) * row[U + r]
    return float(acc)


@njit(cache=True)
def input_change(
    row: Array,
    t_s: float,
    pose: Array,
    contact_rec: Array,
    previous: Array,
    point: Array,
) -> float:
    """The push's change (N along ``u``) at ``t_s`` between the simulated pose (4x4) and the
    recorded contact point; ``previous`` (5,) holds the time and both penetrations the rates
    were last taken from (t < 0: none) and those rates, and is updated; ``point`` is scratch
    (3,). Rates are differences over at least ``RATE_SPAN_S`` (ticks closer than that, which a
    sensor-triggered loop has, would turn a tiny travel into a large rate)."""
    for r in range(3):
        acc = pose[r, 3]
        for c in range(3):
            acc += pose[r, c] * row[POINT + c]
        point[r] = acc
    h = surface_m(row, t_s)
    p_sim = h - _travel_m(row, point)
    p_rec = h - _travel_m(row, contact_rec)
    if previous[0] < 0.0:
        previous[0], previous[1], previous[2], previous[3], previous[4] = t_s, p_sim, p_rec, 0, 0
    elif t_s - previous[0] >= RATE_SPAN_S:
        span = t_s - previous[0]
        previous[3] = (p_sim - previous[1]) / span
        previous[4] = (p_rec - previous[2]) / span
        previous[0], previous[1], previous[2] = t_s, p_sim, p_rec
    rate_sim, rate_rec = previous[3], previous[4]
    mechanics = int(row[MECH])
    if mechanics == 2:
        return 0.0
    k, c = row[STIFFNESS], row[DAMPING]
    return push_n(mechanics, k, c, p_sim, rate_sim) - push_n(mechanics, k, c, p_rec, rate_rec)


@njit(cache=True)
def simulate_kernel(
    t_s: Array,
    force_rec: Array,
    position_d: Array,
    rotation_d: Array,
    contact_rec: Array,
    link_flags: NDArray[np.int64],
    collisions: Array,
    tick_args: tuple[Any, ...],  # CompiledTick.kernel_args()
    inputs: tuple[Any, ...],  # some of them by name: kernel_inputs()
    servo: Array,
    servo_limits: Array,
    commands_t_s: Array,
    commands_q: Array,
    response: Array,
    floats: Array,
    contact_out: NDArray[np.int8],
    row0: int,
    force_row: int,
) -> int:
    """Every tick of the closed loop (module doc); writes the controller's outputs and its input
    into ``floats`` (A, quantities, N) rows ``row0 + k`` and the contact codes into
    ``contact_out``. ``servo`` (4, 6): q, qd, qdd and the target; ``response``: bandwidth
    (rad/s), sub-step and delay (s); returns the ticks run (all of them)."""
    q_measured, extra, position, rotation, out, contact, work, frames, axes = inputs
    q_cmd = work[W_Q_CMD : W_Q_CMD + 6]
    q, qd, qdd, target = servo[0], servo[1], servo[2], servo[3]
    clock = np.array([t_s[0]])
    cursor = np.zeros(1, dtype=np.int64)
    pose = np.eye(4)
    previous = np.array([-1.0, 0.0, 0.0, 0.0, 0.0])
    point = np.zeros(3)
    n, axes_count = t_s.shape[0], force_rec.shape[1]
    current = -1
    for k in range(n):
        t = t_s[k]
        advance(q, qd, qdd, target, clock, t, commands_t_s, commands_q, cursor, k,
                servo_limits, response[0], response[1], response[2])  # fmt: skip
        while current + 1 < collisions.shape[0] and k >= collisions[current + 1, START]:
            current += 1
            previous[0] = -1.0
        for i in range(axes_count):
            extra[i] = force_rec[k, i]
        if current >= 0:
            row = collisions[current]
            fk_into(frames, axes, q, pose)
            change = input_change(row, t, pose, contact_rec[k], previous, point)
            for r in range(3):
                extra[r] += change * row[U + r]
        for j in range(6):
            q_measured[j] = q[j]
        for r in range(3):
            position[r] = position_d[k, r]
            for c in range(3):
                rotation[r, c] = rotation_d[k, r, c]
        tick_kernel(*tick_args, link_flags[k])  # type: ignore[call-arg]
        commands_t_s[k] = t
        for j in range(6):
            commands_q[k, j] = q_cmd[j]
        for i in range(axes_count):
            for quantity in range(4):
                floats[i, quantity, row0 + k] = out[quantity, 0, i]
            floats[i, force_row, row0 + k] = extra[i]
            contact_out[i, row0 + k] = contact[0, i]
    return int(n)


def kernel_inputs(tick: CompiledTick) -> tuple[NDArray[np.generic], ...]:
    """The arrays of ``tick`` that :func:`simulate_kernel` writes or reads by name (``inputs``)."""
    i, k = tick.inputs, tick.arrays
    return (i.q_measured, i.extra, i.position_d, i.rotation_d, k.out, k.contact, tick.work,
            tick.chain.frames, tick.chain.axes)  # fmt: skip
