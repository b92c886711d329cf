"""The emulated AUBO-i5's joint servos: what the arm does with the targets it is sent.

Each joint is a position servo: a critically damped second-order tracker of its target at
``bandwidth_rad_s``, with its velocity and acceleration saturated at the limits and its position
kept inside them. The servo follows targets only in mode TRACK and only while the Modbus
watchdog counter keeps changing: once no new count has arrived for ``watchdog_s`` it holds the
position it has (status HOLDING), as a real controller does when its master goes silent. Mode
STOP latches a protective stop until a HOLD or TRACK write clears it. Single-threaded (the rig's
slot loop); the integration is one compiled kernel call per ``advance``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.drivers.joint_targets.wire import JOINTS, Mode
from hilrig.drivers.robot_state.wire import RobotState, RobotStatus
from hilrig.robot.limits import JointLimits
from hilrig.timing import bound_kernel

MAX_SUBSTEPS = 200  # per advance: at most 0.1 s at the default substep, no catch-up bursts

Vector = NDArray[np.float64]
# the frames' status bits, combined once (IntFlag's | costs a microsecond a slot)
_STOPPED = RobotStatus.ENABLED | RobotStatus.PROTECTIVE_STOP
_TRACKING = RobotStatus.ENABLED | RobotStatus.TRACKING
_HOLDING = RobotStatus.ENABLED | RobotStatus.HOLDING


@njit(cache=True)
def integrate(
    q: Vector,
    qd: Vector,
    qdd: Vector,
    target: Vector,
    hold: bool,
    limits: NDArray[np.float64],
    wn: float,
    dt: float,
    steps: int,
) -> None:
    """``steps`` sub-steps of the saturated servos, in place; ``hold`` tracks q itself.

    ``limits`` rows: q_min, q_max, qd_max, qdd_max.
    """
    for _ in range(steps):
        for j in range(q.shape[0]):
            goal = q[j] if hold else target[j]
            acc = wn * wn * (goal - q[j]) - 2.0 * wn * qd[j]
            acc = min(max(acc, -limits[3, j]), limits[3, j])
            vel = min(max(qd[j] + acc * dt, -limits[2, j]), limits[2, j])
            pos = q[j] + vel * dt
            if pos < limits[0, j] or pos > limits[1, j]:
                pos = min(max(pos, limits[0, j]), limits[1, j])
                vel = 0.0
            q[j] = pos
            qd[j] = vel
            qdd[j] = acc


@njit(cache=True)
def clamp_into(target: Vector, limits: NDArray[np.float64], q_rad: Vector) -> None:
    """``q_rad`` clamped to the position limits (rows q_min, q_max of ``limits``) into
    ``target``."""
    for j in range(target.shape[0]):
        target[j] = min(max(q_rad[j], limits[0, j]), limits[1, j])


def servo_limits(limits: JointLimits) -> NDArray[np.float64]:
    """``limits`` as the servo kernel takes them (rows q_min, q_max, qd_max, qdd_max)."""
    return np.array(
        [
            limits.lower_rad(),
            limits.upper_rad(),
            limits.velocity_max_rad_s,
            limits.acceleration_max_rad_s2,
        ],
        dtype=np.float64,
    )


class JointServoPlant:
    """Six joint servos integrated in fixed sub-steps of ``substep_s`` up to each ``advance``."""

    def __init__(
        self,
        limits: JointLimits,
        *,
        q0_rad: Vector | None = None,
        bandwidth_rad_s: float = 60.0,
        watchdog_s: float = 0.05,
        substep_s: float = 0.0005,
    ) -> None:
        self._limits = servo_limits(limits)
        self._q = np.zeros(JOINTS) if q0_rad is None else np.array(q0_rad, dtype=np.float64)
        self._qd = np.zeros(JOINTS)
        self._qdd = np.zeros(JOINTS)
        self._target = self._q.copy()
        self._wn = bandwidth_rad_s
        self._watchdog_ns = round(watchdog_s * 1e9)
        self._substep_s = substep_s
        self._substep_ns = round(substep_s * 1e9)
        self._mode = Mode.HOLD
        self._stopped = False
        self._last_count: int | None = None
        self._last_count_ns: int | None = None
        self._t_ns: int | None = None
        self._was_tracking = False
        self.targets_received = 0
        self.watchdog_trips = 0
        # the kernel loaded (or compiled) now, not in a slot, bound to the arrays it updates
        self._integrate = bound_kernel(
            integrate,
            self._q,
            self._qd,
            self._qdd,
            self._target,
            last=(True, self._limits, self._wn, self._substep_s, 0),
        )
        self._clamp = bound_kernel(clamp_into, self._target, self._limits, last=(self._q,))

    def set_targets(self, q_rad: Vector, sequence: int, mode: Mode, now_ns: int) -> None:
        """Take one Modbus write: targets (rad, finite; clamped to the position limits), the
        watchdog counter and the mode."""
        self.targets_received += 1
        if sequence != self._last_count:
            self._last_count = sequence
            self._last_count_ns = now_ns
        self._mode = mode
        self._stopped = mode is Mode.STOP
        if mode is Mode.TRACK:
            self._clamp(q_rad)

    def tracking(self, now_ns: int) -> bool:
        """True while the servo follows its targets (TRACK, fresh watchdog count, no stop)."""
        fresh = (
            self._last_count_ns is not None and now_ns - self._last_count_ns <= self._watchdog_ns
        )
        return self._mode is Mode.TRACK and fresh and not self._stopped

    def advance(self, now_ns: int) -> None:
        """Integrate from the last call to ``now_ns`` (host monotonic ns)."""
        if self._t_ns is None:
            self._t_ns = now_ns
            return
        tracking = self.tracking(now_ns)
        if self._was_tracking and not tracking and self._mode is Mode.TRACK:
            self.watchdog_trips += 1  # targets stopped coming: hold
        self._was_tracking = tracking
        steps = (now_ns - self._t_ns) // self._substep_ns
        if steps <= 0:
            return
        # holding servos track the current position: the arm decelerates and stays
        self._step(hold=not tracking, steps=min(steps, MAX_SUBSTEPS))
        self._t_ns += steps * self._substep_ns

    def _step(self, *, hold: bool, steps: int) -> None:
        self._integrate(hold, self._limits, self._wn, self._substep_s, steps)

    def status(self) -> RobotStatus:
        """The status bits a frame sent now carries."""
        if self._stopped:
            return _STOPPED
        if self._t_ns is not None and self.tracking(self._t_ns):
            return _TRACKING
        return _HOLDING

    def state(self, sequence: int, device_t_ns: int, torque_nm: tuple[float, ...]) -> RobotState:
        """The joint-state frame to stream now, with measured joint torques (N*m)."""
        return RobotState(
            sequence,
            device_t_ns,
            tuple(self._q.tolist()),
            tuple(self._qd.tolist()),
            torque_nm,
            self.status(),
        )

    def live_arrays(self) -> tuple[Vector, Vector]:
        """The joint positions (rad) and velocities (rad/s) themselves, updated in place by
        ``advance``: for compiled readers bound to them (read, never write)."""
        return self._q, self._qd

    @property
    def q_rad(self) -> Vector:
        """Joint positions now (a copy)."""
        return self._q.copy()
