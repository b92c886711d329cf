"""The emulated AUBO-i5's joint servos: what the arm does with the targets it is sent.

Each joint is a position servo: a critically damped second-order tracker of its target at
``bandwidth_rad_s``, with its velocity and acceleration saturated at the limits and its position
kept inside them. The servo follows targets only in mode TRACK and only while the Modbus
watchdog counter keeps changing: once no new count has arrived for ``watchdog_s`` it holds the
position it has (status HOLDING), as a real controller does when its master goes silent. Mode
STOP latches a protective stop until a HOLD or TRACK write clears it. Thread-safe: targets
arrive from the Modbus server's thread, ``advance`` runs on the state stream's thread.
"""

from __future__ import annotations

import threading

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.joint_targets_map import JOINTS, JointTargets, Mode
from hilrig.drivers.robot_state_codec import RobotState, RobotStatus
from hilrig.robot.limits import JointLimits


class JointServoPlant:
    """Six joint servos integrated in fixed sub-steps of ``substep_s`` up to each ``advance``."""

    def __init__(
        self,
        limits: JointLimits,
        *,
        q0_rad: NDArray[np.float64] | None = None,
        bandwidth_rad_s: float = 60.0,
        watchdog_s: float = 0.05,
        substep_s: float = 0.0005,
    ) -> None:
        self._q_min = limits.lower_rad()
        self._q_max = limits.upper_rad()
        self._qd_max = np.array(limits.velocity_max_rad_s)
        self._qdd_max = np.array(limits.acceleration_max_rad_s2)
        self._q = np.zeros(JOINTS) if q0_rad is None else np.array(q0_rad, dtype=np.float64)
        self._qd = np.zeros(JOINTS)
        self._qdd = np.zeros(JOINTS)
        self._target = self._q.copy()
        self._wn = bandwidth_rad_s
        self._watchdog_ns = round(watchdog_s * 1e9)
        self._substep_s = substep_s
        self._mode = Mode.HOLD
        self._stopped = False
        self._last_count: int | None = None
        self._last_count_ns: int | None = None
        self._t_ns: int | None = None
        self._was_tracking = False
        self._lock = threading.Lock()
        self.targets_received = 0
        self.watchdog_trips = 0

    def set_targets(self, targets: JointTargets, now_ns: int) -> None:
        """Take one Modbus write (any thread); targets are clamped to the position limits."""
        with self._lock:
            self.targets_received += 1
            if targets.sequence != self._last_count:
                self._last_count = targets.sequence
                self._last_count_ns = now_ns
            self._mode = targets.mode
            self._stopped = targets.mode is Mode.STOP
            if targets.mode is Mode.TRACK:
                self._target = np.clip(np.asarray(targets.q_rad), self._q_min, self._q_max)

    def tracking(self, now_ns: int) -> bool:
        """True while the servo follows its targets (TRACK, fresh watchdog count, no stop)."""
        fresh = (
            self._last_count_ns is not None and now_ns - self._last_count_ns <= self._watchdog_ns
        )
        return self._mode is Mode.TRACK and fresh and not self._stopped

    def advance(self, now_ns: int) -> None:
        """Integrate from the last call to ``now_ns`` (host monotonic ns)."""
        with self._lock:
            if self._t_ns is None:
                self._t_ns = now_ns
                return
            tracking = self.tracking(now_ns)
            if self._was_tracking and not tracking and self._mode is Mode.TRACK:
                self.watchdog_trips += 1  # targets stopped coming: hold
            self._was_tracking = tracking
            steps = int((now_ns - self._t_ns) / (self._substep_s * 1e9))
            for _ in range(min(steps, 200)):  # at most 0.1 s per call: no catch-up bursts
                # holding servos to the current position: the arm decelerates and stays
                self._substep(self._target if tracking else self._q)
            self._t_ns += round(steps * self._substep_s * 1e9)

    def _substep(self, target: NDArray[np.float64]) -> None:
        dt = self._substep_s
        qdd = self._wn**2 * (target - self._q) - 2.0 * self._wn * self._qd
        qdd = np.clip(qdd, -self._qdd_max, self._qdd_max)
        qd = np.clip(self._qd + qdd * dt, -self._qd_max, self._qd_max)
        q = self._q + qd * dt
        at_limit = (q < self._q_min) | (q > self._q_max)
        self._q = np.clip(q, self._q_min, self._q_max)
        self._qd = np.where(at_limit, 0.0, qd)
        self._qdd = qdd

    def state(self, sequence: int, device_t_ns: int, torque_nm: NDArray[np.float64]) -> RobotState:
        """The joint-state frame to stream now, with measured joint torques (N*m)."""
        with self._lock:
            status = RobotStatus.ENABLED
            if self._stopped:
                status |= RobotStatus.PROTECTIVE_STOP
            elif self._t_ns is not None and self.tracking(self._t_ns):
                status |= RobotStatus.TRACKING
            else:
                status |= RobotStatus.HOLDING
            return RobotState(
                sequence,
                device_t_ns,
                tuple(float(v) for v in self._q),
                tuple(float(v) for v in self._qd),
                tuple(float(v) for v in torque_nm),
                status,
            )

    @property
    def q_rad(self) -> NDArray[np.float64]:
        """Joint positions now (a copy)."""
        with self._lock:
            return self._q.copy()
