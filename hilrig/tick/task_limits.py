"""Whether a task keeps inside the safety clamp's limits, with margin, checked before it runs.

The clamp (:mod:`.safety`) bounds every commanded step in joint space: position (with the
braking distance to the limit), velocity, acceleration, and the TCP inside the workspace box
(with its braking distance). A task that asks for more is clipped, and each time the clamp
engages it logs a safety event that nobody caused. So a task is checked once, as its session
is set up, the way the loop runs it: sampled on the tick grid (t = k dt from the start at rest),
taken to the joints by the tick's inverse kinematics from the start joints, and differenced as
the clamp differences its commands (v = dq/dt, a = dv/dt, jerk = da/dt). Velocity, acceleration
and jerk must stay within ``TASK_MARGIN`` of the joint limits (jerk: ``jerk_max_rad_s3``, which
the tasks keep and the clamp does not bound); joint positions and the TCP must pass the clamp's
own tests. A task that does not is refused in one line naming it, the joint, the limit and by
how much (:class:`~hilrig.errors.ParameterError`); a task's parameters are never changed.

What is checked is what a session runs of the task, from rest: a circle's ramp and one lap, the
square's four sides back to the start, a waypoint path to its last point and its stop; no
longer than the session. The inverse kinematics runs compiled, a chunk of samples a call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.errors import ParameterError
from hilrig.robot import IK_ERRORS, CompiledChain, ik_into, ik_work
from hilrig.tick.clamp_kernels import AMAX, HI, LO, REACH
from hilrig.tick.safety import SafetyClamp
from hilrig.tick.trajectory import Circle, Trajectory
from hilrig.tick.trajectory_kernel import desired_writer

TASK_MARGIN = 0.8  # of each joint's velocity, acceleration and jerk limit
CHUNK = 8192  # samples per compiled call
IK_TOLERANCE = 1e-12  # m and rad: far below a tick's step, so the differences are the path's
IK_ITERATIONS = 50
REACHED = 1e-8  # m and rad: the tick's own tolerance; a pose IK cannot meet to this is out of reach
REACH_FAILED, POSITION_FAILED, BOX_FAILED = 1, 2, 3
QUANTITIES = (("velocity", "rad/s"), ("acceleration", "rad/s^2"), ("jerk", "rad/s^3"))
HINTS = {
    "circle": "a longer period_s or ramp_s, or a smaller radius_m",
    "square": "a longer side_duration_s or a shorter side_m",
    "waypoints": "later times or nearer points",
}


@dataclass(frozen=True, slots=True)
class TaskPeaks:
    """The largest |velocity|, |acceleration| and |jerk| of each joint over the span checked,
    (3, 6) in rad/s, rad/s^2 and rad/s^3 (rows in that order), and the first bound of the
    clamp's the path fails (``POSITION_FAILED``, ``BOX_FAILED``; 0: none) and when (s)."""

    peaks: NDArray[np.float64]
    failure: int
    failure_t_s: float


def lap_s(trajectory: Trajectory) -> float:
    """How long from the start a session must run to meet all of ``trajectory``'s motion (s)."""
    if isinstance(trajectory, Circle):
        return trajectory.ramp_s + trajectory.period_s
    return trajectory.duration_s


def task_peaks(name: str, trajectory: Trajectory, clamp: SafetyClamp, span_s: float) -> TaskPeaks:
    """The joints' peaks over ``span_s`` s of ``trajectory`` from rest at the clamp's start
    joints, sampled at its tick; ParameterError (one line) where the path leaves the arm's
    reach."""
    dt = clamp.config.dt_s
    chain = CompiledChain.from_model(clamp.model)
    limits, box, _ = clamp.kernel_arrays()
    history = np.zeros((3, 6))  # the last q, v and a: at rest on the start joints
    history[0] = clamp.q_rad
    peaks, failure = np.zeros((3, 6)), np.array([-1, 0], dtype=np.int64)
    rotation = np.ascontiguousarray(trajectory.rotation)
    position, chunk, work = np.zeros(3), np.zeros((CHUNK, 3)), ik_work()
    write = desired_writer(trajectory, position)
    samples = math.ceil(span_s / dt) + 3  # and its stop, at rest
    for first in range(1, samples + 1, CHUNK):
        count = min(CHUNK, samples + 1 - first)
        for i in range(count):
            write((first + i) * dt)
            chunk[i] = position
        failed = failure[0]
        reached = joint_peaks(
            chain.frames, chain.axes, chain.limits, limits, box, rotation, chunk[:count],
            dt, history, peaks, work, failure,
        )  # fmt: skip
        if failed < 0 <= failure[0]:
            failure[0] += first
        if reached < count:
            _refuse(name, trajectory, REACH_FAILED, (first + reached) * dt)
    return TaskPeaks(peaks, int(failure[1]), failure[0] * dt)


def check_task(
    name: str, trajectory: Trajectory, clamp: SafetyClamp, duration_s: float | None = None
) -> TaskPeaks:
    """Refuse (ParameterError, one line) a task ``name`` that would take a joint above
    ``TASK_MARGIN`` of its velocity, acceleration or jerk limit, or out of the clamp's bounds,
    in the first ``duration_s`` s (default: all of its motion); else return its peaks."""
    span_s = lap_s(trajectory) if duration_s is None else min(lap_s(trajectory), duration_s)
    found = task_peaks(name, trajectory, clamp, span_s)
    limits = clamp.config.limits
    allowed = TASK_MARGIN * np.array(
        [limits.velocity_max_rad_s, limits.acceleration_max_rad_s2, limits.jerk_max_rad_s3]
    )
    ratio = found.peaks / allowed
    row, joint = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    if ratio[row, joint] > 1.0:
        quantity, unit = QUANTITIES[row]
        peak, within = found.peaks[row, joint], allowed[row, joint]
        raise ParameterError(
            f"trajectory {name!r}: joint {joint + 1} {quantity} {peak:.3g} {unit} is "
            f"{100 * (peak / within - 1):.0f} % over {100 * TASK_MARGIN:.0f} % of its limit "
            f"({within:.3g} of {within / TASK_MARGIN:.3g} {unit}); try "
            f"{HINTS.get(name, 'a slower task')}"
        )
    if found.failure:
        _refuse(name, trajectory, found.failure, found.failure_t_s)
    return found


def _refuse(name: str, trajectory: Trajectory, reason: int, t_s: float) -> None:
    position = np.zeros(3)
    trajectory.desired(t_s, position)
    what = {
        REACH_FAILED: "leaves the arm's reach",
        POSITION_FAILED: "takes a joint past its limit (less the clamp's margin and braking)",
        BOX_FAILED: "leaves the safety clamp's workspace box (with its braking distance)",
    }[reason]
    tcp = ", ".join(f"{x:.3f}" for x in position)
    raise ParameterError(f"trajectory {name!r} {what} at t = {t_s:.3f} s, TCP ({tcp}) m")


@njit(cache=True, error_model="numpy")
def joint_peaks(
    frames: NDArray[np.float64],
    axes: NDArray[np.float64],
    joint_limits: NDArray[np.float64],
    clamp_limits: NDArray[np.float64],
    box: NDArray[np.float64],
    rotation: NDArray[np.float64],
    positions: NDArray[np.float64],
    dt: float,
    history: NDArray[np.float64],
    peaks: NDArray[np.float64],
    work: NDArray[np.float64],
    failure: NDArray[np.int64],
) -> int:
    """One chunk of desired TCP positions (n, 3) to joints by IK, warm-started from
    ``history[0]`` (then q, v, a of the last sample); the largest |v|, |a|, |jerk| per joint
    into ``peaks`` (3, 6); the first sample (index, reason) that fails a joint's bounds or the
    box into ``failure`` unless it holds one. Returns how many samples IK reached (n: all)."""
    goal = np.eye(4)
    goal[:3, :3] = rotation
    q = history[0].copy()
    samples: int = positions.shape[0]
    for k in range(samples):
        for r in range(3):
            goal[r, 3] = positions[k, r]
        code = ik_into(frames, axes, joint_limits, goal, q, IK_ITERATIONS, IK_TOLERANCE,
                       IK_TOLERANCE, 1e-4, 0.5, work)  # fmt: skip
        if code < 0 and not max(work[IK_ERRORS, 0], work[IK_ERRORS, 1]) <= REACHED:
            return k
        reason, rho = 0, 0.0
        for j in range(q.shape[0]):
            v = (q[j] - history[0, j]) / dt
            a = (v - history[1, j]) / dt
            jerk = (a - history[2, j]) / dt
            history[0, j], history[1, j], history[2, j] = q[j], v, a
            peaks[0, j] = max(peaks[0, j], abs(v))
            peaks[1, j] = max(peaks[1, j], abs(a))
            peaks[2, j] = max(peaks[2, j], abs(jerk))
            stop = q[j] + v * abs(v) / (2.0 * clamp_limits[AMAX, j])  # where braking ends
            if not clamp_limits[LO, j] <= stop <= clamp_limits[HI, j]:
                reason = POSITION_FAILED
            rho += clamp_limits[REACH, j] * v * v / (2.0 * clamp_limits[AMAX, j])
        for r in range(3):
            if reason == 0 and not box[0, r] + rho <= positions[k, r] <= box[1, r] - rho:
                reason = BOX_FAILED
        if reason and failure[0] < 0:
            failure[0], failure[1] = k, reason
    return samples
