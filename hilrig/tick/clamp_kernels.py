"""The safety clamp's compiled kernels and its flags (the argument is in ``safety.py``).

The kernels work on packed, preallocated arrays, so the rig's compiled tick calls them directly:
``candidate`` builds the joint-limited step toward a target, ``finish`` commits it (or the brake
step when holding or when its TCP pose fails the workspace test), ``exceeds`` tells a protective
stop. Row layouts: limits (5, 6) LO, HI, VMAX, AMAX, REACH; state (6, 6) Q, V, TARGET, CAND_Q,
CAND_V, CAND_TARGET.
"""

from __future__ import annotations

import enum
import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit


class Clamp(enum.IntFlag):
    """What engaged on a tick (bitmask returned by ``clamp`` and ``hold``); 0: target sent as is."""

    POSITION = 1  # a target beyond the limits, or the braking distance to a limit, bound a joint
    VELOCITY = 2  # the joint velocity limit bound a joint
    ACCELERATION = 4  # the acceleration limit bound a joint (also: braking onto a jumped target)
    WORKSPACE = 8  # the step would have let the TCP leave the box: braked instead
    NON_FINITE = 16  # the target held NaN or inf: braked instead
    HOLDING = 32  # a controlled stop (hold() or a non-finite target): braking toward standstill


POSITION, VELOCITY = int(Clamp.POSITION), int(Clamp.VELOCITY)
ACCELERATION, WORKSPACE = int(Clamp.ACCELERATION), int(Clamp.WORKSPACE)
NON_FINITE, HOLDING = int(Clamp.NON_FINITE), int(Clamp.HOLDING)
# A gap to the target below this is closed in one tick (a velocity change < 1e-9 rad/s at 1 kHz).
SNAP_RAD = 1e-12
# Rows of the packed joint limits (5, 6) and state (6, 6) the kernels share.
LO, HI, VMAX, AMAX, REACH = range(5)
Q, V, TARGET, CAND_Q, CAND_V, CAND_TARGET = range(6)


@njit(cache=True, inline="always")
def stop_speed(distance: float, a: float, dt: float) -> float:
    """The largest speed v >= 0 toward a wall ``distance`` away with v*dt + v**2/(2a) <= distance.

    Moving one tick at v then braking at ``a`` stops before the wall. Written without the
    cancellation of ``sqrt(x**2 + 2 a d) - x``.
    """
    if distance <= 0.0:
        return 0.0
    x = a * dt
    return 2.0 * a * distance / (math.sqrt(x * x + 2.0 * a * distance) + x)


@njit(cache=True)
def candidate(
    target: NDArray[np.float64], lim: NDArray[np.float64], st: NDArray[np.float64], dt: float
) -> int:
    """The joint-limited step toward ``target`` into st[CAND_*]; its flags, or NON_FINITE alone."""
    for j in range(target.shape[0]):
        if not math.isfinite(target[j]):
            return NON_FINITE
    flags = 0
    for j in range(target.shape[0]):
        lo, hi, v_max, a = lim[LO, j], lim[HI, j], lim[VMAX, j], lim[AMAX, j]
        q, v, last_target = st[Q, j], st[V, j], st[TARGET, j]
        t = target[j]
        if t < lo or t > hi:
            t = min(max(t, lo), hi)
            flags |= POSITION
        v_want = (t - q) / dt
        approaching = False
        gap = last_target - q  # zero when the previous tick reached its target
        if gap != 0.0:
            v_approach = (t - last_target) / dt + math.copysign(stop_speed(abs(gap), a, dt), gap)
            if abs(v_want - v_approach) * dt > SNAP_RAD:
                v_want = v_approach
                approaching = True
        up_v, up_a, up_p = v_max, v + a * dt, stop_speed(hi - q, a, dt)
        down_v, down_a, down_p = -v_max, v - a * dt, -stop_speed(q - lo, a, dt)
        up = min(up_v, up_a, up_p)
        down = max(down_v, down_a, down_p)
        v_new = min(max(v_want, down), up)
        if v_new == v_want and not approaching:
            q_new = t
        else:
            q_new = q + v_new * dt
            if v_new == v_want:
                flags |= ACCELERATION
            elif v_new == up:
                flags |= flags_of(v_new, up_v, up_a, up_p)
            else:
                flags |= flags_of(v_new, down_v, down_a, down_p)
        if q_new < lo or q_new > hi:  # only ever by rounding
            q_new = min(max(q_new, lo), hi)
            flags |= POSITION
        st[CAND_Q, j] = q_new
        st[CAND_V, j] = (q_new - q) / dt
        st[CAND_TARGET, j] = t
    return flags


@njit(cache=True, inline="always")
def flags_of(v: float, by_velocity: float, by_acceleration: float, by_position: float) -> int:
    flags = 0
    if v == by_velocity:
        flags |= VELOCITY
    if v == by_acceleration:
        flags |= ACCELERATION
    if v == by_position:
        flags |= POSITION
    return flags


@njit(cache=True)
def finish(
    pose: NDArray[np.float64],
    box: NDArray[np.float64],
    lim: NDArray[np.float64],
    st: NDArray[np.float64],
    dt: float,
    out: NDArray[np.float64],
    hold: bool,
) -> int:
    """Commit the candidate, or the brake step when holding or the candidate fails (W).

    ``pose`` is the candidate's TCP pose (4x4, base frame, m), unused when holding. Returns
    WORKSPACE when the candidate was refused for the box, else 0; writes ``out``.
    """
    joints = st.shape[1]
    braked = 0
    if not hold:
        rho = 0.0
        for j in range(joints):
            v = st[CAND_V, j]
            rho += lim[REACH, j] * v * v / (2.0 * lim[AMAX, j])
        for k in range(3):
            if not (box[0, k] + rho <= pose[k, 3] <= box[1, k] - rho):
                braked = WORKSPACE
    if hold or braked:
        for j in range(joints):
            v, dv = st[V, j], lim[AMAX, j] * dt
            v_new = v - dv if v > dv else (v + dv if v < -dv else 0.0)
            q = st[Q, j]
            q_new = min(max(q + v_new * dt, lim[LO, j]), lim[HI, j])
            st[CAND_Q, j] = q_new
            st[CAND_V, j] = (q_new - q) / dt
    for j in range(joints):
        q_new = st[CAND_Q, j]
        st[Q, j] = q_new
        st[V, j] = st[CAND_V, j]
        # after a stop, the next target's jump is measured from where the stop got to
        st[TARGET, j] = q_new if hold else st[CAND_TARGET, j]
        out[j] = q_new
    return braked


@njit(cache=True)
def exceeds(
    force: NDArray[np.float64], torque: NDArray[np.float64], force_max: float, torque_max: float
) -> bool:
    force_sq = force[0] * force[0] + force[1] * force[1] + force[2] * force[2]
    exceeded = not force_sq <= force_max * force_max  # NaN exceeds
    for j in range(torque.shape[0]):
        exceeded |= not abs(torque[j]) <= torque_max
    return exceeded
