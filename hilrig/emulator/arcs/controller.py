"""The emulated ARCS controller's state: modes, servo mode, users, faults and this slot's values.

What the JSON-RPC and RTDE servers read and change, in the rig's one loop thread. Its rules
(docs/protocols.md, "ARCS"):

- ``servo_joint(q)`` is accepted (0) only with safety mode Normal, robot mode Running and servo
  mode on, and a q of 6 finite numbers inside the joint limits; it then feeds the plant
  (``Mode.TRACK``) with a counter that counts accepted calls, so the plant's watchdog holds the
  arm when calls stop. Otherwise the code AUBO documents for servoJoint (motion_control.h):
  AUBO_BAD_STATE (1, safety mode not Normal), -AUBO_BAD_STATE (-1, robot mode not Running),
  -AUBO_REQUEST_IGNORE (-13, not in servo mode), -AUBO_INVL_ARGUMENT (-5, bad q), in that order;
- servo mode left (``set_servo_mode(False)``, a fault, or no servoJoint for ``servo_timeout_s``)
  holds the arm (``Mode.HOLD``);
- a protective stop (safety mode ProtectiveStop) or an emergency stop (RobotEmergencyStop, and
  robot mode Idle: the brakes are on) leaves servo mode and latches the plant's ``Mode.STOP``
  until ``reset()``.

Faults come from any thread and apply at the next ``tick``; the RPC and RTDE servers see
``link_epoch`` (dropped links) and ``rtde_stalled`` themselves.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.joint_targets.wire import JOINTS, Mode
from hilrig.emulator.arcs.wire import login_token

Vector = NDArray[np.float64]
# the plant's set_targets: (q rad, watchdog counter, mode, host monotonic ns)
ServoSink = Callable[[Vector, int, Mode, int], None]

INTERFACE_VERSION = 24001  # SystemInfo.getInterfaceVersionCode: what 0.24.1 accepts
ROBOT_NAME = "rob1"
# N*m per A at the joint's output, chosen (not AUBO's figures): the i5's three large joint
# modules (base, shoulder, elbow) and its three small wrist modules
TORQUE_CONSTANTS_NM_PER_A = (10.0, 10.0, 10.0, 6.0, 6.0, 6.0)


class RobotMode(IntEnum):
    """pyaubo_sdk.RobotModeType: its names (on the wire) and values."""

    NoController = -1
    Disconnected = 0
    ConfirmSafety = 1
    Booting = 2
    PowerOff = 3
    PowerOn = 4
    Idle = 5
    BrakeReleasing = 6
    BackDrive = 7
    Running = 8
    Maintaince = 9  # sic
    Error = 10
    PowerOffing = 11


class SafetyMode(IntEnum):
    """pyaubo_sdk.SafetyModeType: its names (on the wire) and values."""

    Undefined = 0
    Normal = 1
    ReducedMode = 2
    Recovery = 3
    Violation = 4
    ProtectiveStop = 5
    SafeguardStop = 6
    SystemEmergencyStop = 7
    RobotEmergencyStop = 8
    Fault = 9


class ServoCode(IntEnum):
    """servoJoint's results (pyaubo_sdk.AuboErrorCodes, signed as motion_control.h says)."""

    OK = 0
    SAFETY_NOT_NORMAL = 1  # AUBO_BAD_STATE
    NOT_RUNNING = -1  # -AUBO_BAD_STATE
    INVALID_ARGUMENT = -5  # -AUBO_INVL_ARGUMENT
    NOT_SERVO_MODE = -13  # -AUBO_REQUEST_IGNORE


@dataclass(frozen=True)
class ArcsConfig:
    """The emulated controller's settings."""

    users: tuple[tuple[str, str], ...] = (("aubo", "123456"),)  # (user, password)
    servo_timeout_s: float = 0.1  # servo mode ends after this long without a servoJoint
    torque_constants_nm_per_a: tuple[float, ...] = TORQUE_CONSTANTS_NM_PER_A


class ArcsController:
    """Modes, servo mode and this slot's joint values of the emulated controller."""

    def __init__(
        self,
        sink: ServoSink,
        *,
        q_rad: Vector,
        qd_rad_s: Vector,
        torque_nm: Vector,
        q_limits_rad: tuple[Vector, Vector],
        config: ArcsConfig | None = None,
    ) -> None:
        self.config = config = ArcsConfig() if config is None else config
        self._sink = sink
        self.q_rad, self.qd_rad_s, self.torque_nm = q_rad, qd_rad_s, torque_nm  # live arrays
        self.current_a = np.zeros(JOINTS)  # torque / constants, each slot
        self.target_q_rad = q_rad.copy()  # the last accepted servoJoint's q
        self._constants = np.asarray(config.torque_constants_nm_per_a, dtype=np.float64)
        self._q_min, self._q_max = q_limits_rad
        self._tokens = {user: login_token(password) for user, password in config.users}
        self._timeout_ns = round(config.servo_timeout_s * 1e9)
        self._requests: deque[Callable[[int], None]] = deque()
        self.robot_mode = RobotMode.Running
        self.safety_mode = SafetyMode.Normal
        self.servo_mode = False
        self._last_servo_ns = 0
        self._counter = 0
        self.time_s = 0.0  # this slot's deadline since the controller started
        self._t0_ns: int | None = None
        self.link_epoch = 0  # advanced by drop_links(): the servers close every client
        self._stall_until_ns = 0
        self._slot_ns = 0
        self._refuse_logins = 0
        self.servo_joints = 0  # accepted servoJoint calls applied to the plant
        self.servo_refused = 0
        self.servo_timeouts = 0
        self.logins = self.logins_refused = 0

    # -- the loop's thread -------------------------------------------------------------------

    def start(self, t0_ns: int) -> None:
        """The controller's clock starts at ``t0_ns`` (host monotonic ns)."""
        self._t0_ns = t0_ns

    def tick(self, slot_ns: int) -> None:
        """Apply faults, end servo mode after ``servo_timeout_s`` of silence, update currents."""
        while self._requests:
            self._requests.popleft()(slot_ns)
        self._slot_ns = slot_ns
        if self._t0_ns is not None:
            self.time_s = (slot_ns - self._t0_ns) * 1e-9
        if self.servo_mode and slot_ns - self._last_servo_ns > self._timeout_ns:
            self.servo_timeouts += 1
            self._leave_servo(time.monotonic_ns())
        np.divide(self.torque_nm, self._constants, out=self.current_a)

    @property
    def rtde_stalled(self) -> bool:
        """True while an injected stall holds the RTDE pushes."""
        return self._slot_ns < self._stall_until_ns

    def login(self, user: str, token: str) -> bool:
        """Check a login (a refused-login fault fails it whatever the password)."""
        if self._refuse_logins > 0:
            self._refuse_logins -= 1
            self.logins_refused += 1
            return False
        ok = self._tokens.get(user) == token
        self.logins += ok
        self.logins_refused += not ok
        return ok

    def set_servo_mode(self, enable: bool, now_ns: int) -> int:
        """setServoMode: 0, or the servoJoint code that says why servo mode cannot start."""
        if not enable:
            if self.servo_mode:
                self._leave_servo(now_ns)
            return 0
        code = self._state_code()
        if code:
            return code
        if not self.servo_mode:
            self.servo_mode = True
            self._last_servo_ns = now_ns
            self._sink(self.q_rad, self._counter, Mode.HOLD, now_ns)
        return 0

    def servo_joint(self, q: object, now_ns: int) -> int:
        """servoJoint: feed ``q`` (rad) to the plant and return 0, or refuse it with a code."""
        code = self._state_code() or (0 if self.servo_mode else ServoCode.NOT_SERVO_MODE)
        if not code and not self._valid_q(q):
            code = ServoCode.INVALID_ARGUMENT
        if code:
            self.servo_refused += 1
            return int(code)
        assert isinstance(q, list)
        self.target_q_rad[:] = q
        self._counter += 1
        self._last_servo_ns = now_ns
        self._sink(self.target_q_rad, self._counter, Mode.TRACK, now_ns)
        self.servo_joints += 1
        return 0

    def stop_joint(self, now_ns: int) -> int:
        """stopJoint: the arm decelerates and holds (servo mode unchanged)."""
        if self.safety_mode is SafetyMode.Normal:
            self._sink(self.q_rad, self._counter, Mode.HOLD, now_ns)
        return 0

    # -- faults (any thread; applied at the next slot) ---------------------------------------

    def protective_stop(self) -> None:
        """Safety mode ProtectiveStop: servo mode left, the arm stopped (``Mode.STOP``)."""
        self._requests.append(lambda _: self._stop(SafetyMode.ProtectiveStop, self.robot_mode))

    def emergency_stop(self) -> None:
        """Safety mode RobotEmergencyStop, robot mode Idle: servo mode left, the arm stopped."""
        self._requests.append(lambda _: self._stop(SafetyMode.RobotEmergencyStop, RobotMode.Idle))

    def reset(self) -> None:
        """Back to Normal and Running, the arm holding (a test's shortcut, not an ARCS call)."""
        self._requests.append(lambda _: self._reset())

    def drop_links(self) -> None:
        """Close every RPC and RTDE client connection."""
        self._requests.append(lambda _: setattr(self, "link_epoch", self.link_epoch + 1))

    def stall_rtde(self, duration_s: float) -> None:
        """Push no RTDE sample for ``duration_s`` (the samples of that time are not sent)."""
        self._requests.append(
            lambda slot_ns: setattr(self, "_stall_until_ns", slot_ns + round(duration_s * 1e9))
        )

    def servo_timeout(self) -> None:
        """Leave servo mode now, as when servo points stop coming."""
        self._requests.append(lambda _: self._timeout_now())

    def refuse_login(self, count: int = 1) -> None:
        """The next ``count`` logins fail as a wrong password does."""
        self._requests.append(lambda _: setattr(self, "_refuse_logins", int(count)))

    # -- internals ---------------------------------------------------------------------------

    def _state_code(self) -> int:
        if self.safety_mode is not SafetyMode.Normal:
            return ServoCode.SAFETY_NOT_NORMAL
        if self.robot_mode is not RobotMode.Running:
            return ServoCode.NOT_RUNNING
        return 0

    def _valid_q(self, q: object) -> bool:
        if not isinstance(q, list) or len(q) != JOINTS:
            return False
        values: Sequence[object] = q
        for j, value in enumerate(values):
            if isinstance(value, bool) or not isinstance(value, int | float):
                return False
            if not math.isfinite(value) or not self._q_min[j] <= value <= self._q_max[j]:
                return False
        return True

    def _leave_servo(self, now_ns: int) -> None:
        self.servo_mode = False
        self._sink(self.q_rad, self._counter, Mode.HOLD, now_ns)

    def _timeout_now(self) -> None:
        if self.servo_mode:
            self.servo_timeouts += 1
            self._leave_servo(time.monotonic_ns())

    def _stop(self, safety: SafetyMode, robot: RobotMode) -> None:
        self.safety_mode, self.robot_mode = safety, robot
        self.servo_mode = False
        self._sink(self.q_rad, self._counter, Mode.STOP, time.monotonic_ns())

    def _reset(self) -> None:
        self.safety_mode, self.robot_mode = SafetyMode.Normal, RobotMode.Running
        self.servo_mode = False
        self._sink(self.q_rad, self._counter, Mode.HOLD, time.monotonic_ns())
