"""The ARCS link's process: AUBO's own client (pyaubo-sdk) talking to the controller.

AUBO's client blocks in its calls while holding the GIL, and runs its RTDE callbacks on threads
of its own: so it runs here, in a process of its own, never on the loop's thread or under its
GIL. Shared-memory rings (:mod:`.shared`) carry the loop's joint targets in and the joint
states and servo calls out; the pipe carries requests ("servo on", "stop") and reports.

Order: connect and log in over JSON-RPC, name the robot, connect and log in to RTDE, subscribe
the joint-state topic, report ``ready``; on "servo on", enter servo mode (refused unless the
robot runs with safety mode Normal) and stream ``servoJoint`` every servo period with the
newest targets; on "servo off" leave servo mode (the states stream on); on "stop", the
parent's end (EOF) or any fault, leave servo mode and log out.
A fault (protective or emergency stop seen over RTDE, a refused servoJoint, a lost link) is
reported once as ``("fault", line)`` and ends the servo stream.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections import deque
from collections.abc import Iterator
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from hilrig.rig.arcs.settings import ArcsSettings
from hilrig.rig.arcs.shared import (
    EMERGENCY_STOP,
    ENABLED,
    FAULT,
    HOLD,
    NO_ANSWER,
    PROTECTIVE_STOP,
    STOP,
    TRACKING,
    Rings,
    RingSpecs,
    newest_row,
)
from hilrig.rig.child import report
from hilrig.robot.limits import AUBO_I5_LIMITS
from hilrig.timing import LatencyHistogram, freeze_heap, raise_priority, tighten_timer_slack

# the controller's clock (s since it started) first: replay aligns the states on it
TOPIC = (
    "timestamp",
    "R1_actual_q",
    "R1_actual_qd",
    "R1_joint_torque_sensor",
    "R1_robot_mode",
    "R1_safety_mode",
)
RUNNING = 8  # RobotModeType.Running
ROBOT_ERROR = 10  # RobotModeType.Error
NORMAL = 1  # SafetyModeType.Normal
PROTECTIVE = (5, 6)  # ProtectiveStop, SafeguardStop
EMERGENCY = (7, 8)  # SystemEmergencyStop, RobotEmergencyStop
SAFETY_NAMES = {
    0: "undefined",
    1: "normal",
    2: "reduced",
    3: "recovery",
    4: "violation",
    5: "protective stop",
    6: "safeguard stop",
    7: "system emergency stop",
    8: "robot emergency stop",
    9: "fault",
}
STOP_ACC_RAD_S2 = 3.0  # stopJoint's deceleration: the i5's joint acceleration limit
# A servo call the client gave up on waits at most this long (the client's own default, 10 ms,
# failed single servoJoint calls on a loaded machine); so many in a row end the session. Calls
# outside servo mode (connect, login, mode changes) wait up to SETUP_TIMEOUT_MS: no tick waits
REQUEST_TIMEOUT_MS, SETUP_TIMEOUT_MS = 50, 2000
MAX_FAILED_CALLS = 3
LINK_PRIORITY = 45  # SCHED_FIFO: below the loop's 50, above the emulated rig's 40
LOG_LINES = 20  # the client's last log lines kept for an error message


class LinkFaultError(Exception):
    """Why the link ends (one line)."""


def _status(robot_mode: int, safety_mode: int, servoing: bool) -> int:
    status = ENABLED if robot_mode == RUNNING else 0
    if safety_mode in PROTECTIVE:
        status |= PROTECTIVE_STOP
    elif safety_mode in EMERGENCY:
        status |= EMERGENCY_STOP
    elif safety_mode != NORMAL or robot_mode == ROBOT_ERROR:
        status |= FAULT
    if servoing and status == ENABLED:
        status |= TRACKING
    return status


class _Link:
    """The client's side of one controller, in this process."""

    def __init__(self, conn: Connection, settings: ArcsSettings, rings: Rings) -> None:
        import pyaubo_sdk

        self._sdk = pyaubo_sdk
        self.conn = conn
        self.settings = settings
        self.rings = rings
        self.log: deque[str] = deque(maxlen=LOG_LINES)
        self._report_lock = threading.Lock()  # the pipe: this thread and the RTDE callback's
        self.rpc = pyaubo_sdk.RpcClient()
        self.rpc.setLogHandler(self._on_log)
        self.rpc.setRequestTimeout(SETUP_TIMEOUT_MS)
        self.rtde = pyaubo_sdk.RtdeClient()
        self.servoing = False
        self.faulted = ""
        self.samples = 0
        self.servo_calls = 0
        self.servo_missed = 0
        self.servo_failed = 0  # calls that got no answer
        self.servo_lateness = LatencyHistogram()
        LatencyHistogram().add(0)  # its kernel loaded now, not at the first servo period
        self.last_q: list[float] = []
        self.robot_mode = -1
        self.safety_mode = 0
        self._limits = AUBO_I5_LIMITS
        self._command = np.zeros(1, dtype=rings.commands.spec.dtype)
        # loaded (or compiled) now, not at the first servo period: the ring is still empty
        newest_row(rings.commands.rows, rings.commands.header, self._command)

    def _on_log(self, level: int, filename: str, line: int, message: str) -> None:
        self.log.append(message.strip())

    def say(self, kind: str, value: object = None) -> None:
        with self._report_lock:
            report(self.conn, kind, value)

    def fault(self, line: str) -> None:
        """Report the first fault once; the servo stream ends at its next period."""
        if not self.faulted:
            self.faulted = line
            self.say("fault", line)

    # -- connecting -------------------------------------------------------------------------

    def connect(self) -> dict[str, Any]:
        s = self.settings
        _log_in(self.rpc, "JSON-RPC", s.rpc_port, s)
        names = list(self.rpc.getRobotNames())
        if not names:
            raise LinkFaultError("the controller names no robot")
        robot = self.rpc.getRobotInterface(names[0])
        self.motion = robot.getMotionControl()
        self.state = robot.getRobotState()
        version = int(self.rpc.getSystemInfo().getInterfaceVersionCode())
        with _stderr_muted():  # the RTDE client logs there until it has a handler
            topic = self._subscribe()
        if topic < 0:
            raise LinkFaultError(f"RTDE refused the joint-state topic at {s.rtde_rate_hz:g} Hz")
        return {
            "robot": names[0],
            "interface_version": version,
            "robot_mode": int(self.state.getRobotModeType()),
            "safety_mode": int(self.state.getSafetyModeType()),
        }

    def _subscribe(self) -> int:
        """Connect and log in to RTDE, subscribe the joint-state topic; its channel (< 0: the
        topic was refused). The log handler comes last: set before ``setTopic``, it makes
        ``setTopic`` return -1 (pyaubo-sdk 0.24.1, observed)."""
        s = self.settings
        _log_in(self.rtde, "RTDE", s.rtde_port, s)
        topic = int(self.rtde.setTopic(False, list(TOPIC), s.rtde_rate_hz, 0))
        if topic >= 0:
            self.rtde.subscribe(topic, self._on_sample)
        self.rtde.setLogHandler(self._on_log)
        return topic

    def _on_sample(self, parser: Any) -> None:
        """One RTDE sample (the client's thread): a joint-state row into the loop's ring."""
        t_ns = time.monotonic_ns()
        device_t_ns = round(parser.popDouble() * 1e9)
        q, qd, tau = parser.popVectorDouble(), parser.popVectorDouble(), parser.popVectorDouble()
        robot_mode, safety_mode = int(parser.popRobotModeType()), int(parser.popSafetyModeType())
        self.samples += 1
        self.last_q = q
        ring = self.rings.states
        slot = ring.reserve()
        if slot is not None:
            slot["t_ns"], slot["device_t_ns"], slot["seq"] = t_ns, device_t_ns, self.samples
            slot["q"], slot["qd"], slot["tau"] = q, qd, tau
            slot["status"] = _status(robot_mode, safety_mode, self.servoing)
            ring.commit()
        if (robot_mode, safety_mode) != (self.robot_mode, self.safety_mode):
            self.robot_mode, self.safety_mode = robot_mode, safety_mode
            if self.servoing and safety_mode != NORMAL:
                name = SAFETY_NAMES.get(safety_mode, str(safety_mode))
                self.fault(f"the controller reports {name} (safety mode {safety_mode})")
            elif self.servoing and robot_mode != RUNNING:
                self.fault(f"the robot left running (robot mode {robot_mode})")

    # -- servo --------------------------------------------------------------------------------

    def servo_on(self) -> None:
        """Enter servo mode: only once a fresh state shows the robot running, safety normal."""
        if self.samples == 0:
            raise LinkFaultError("no RTDE joint state yet: servo mode not entered")
        if self.robot_mode != RUNNING or self.safety_mode != NORMAL:
            name = SAFETY_NAMES.get(self.safety_mode, str(self.safety_mode))
            raise LinkFaultError(
                f"servo mode not entered: robot mode {self.robot_mode}, safety {name}"
            )
        code = self.motion.setServoMode(True)
        if code != 0 or not self.motion.isServoModeEnabled():
            raise LinkFaultError(f"the controller did not enter servo mode (code {code})")
        # until the loop's first targets: hold where the arm is (a controller in servo mode
        # that gets no point leaves it)
        self._command[0]["mode"], self._command[0]["source_ns"] = HOLD, 0
        self._command[0]["q"] = self.last_q
        self.rpc.setRequestTimeout(REQUEST_TIMEOUT_MS)
        self.servoing = True

    def servo_off(self) -> None:
        """Leave servo mode (quietly: also on a link already lost)."""
        if self.servoing:
            self.servoing = False
            with contextlib.suppress(Exception):
                self.rpc.setRequestTimeout(SETUP_TIMEOUT_MS)
                self.motion.setServoMode(False)

    def serve(self) -> None:
        """Stream servoJoint every period until "stop", EOF or a fault; leave servo mode.

        Calls sit on a grid of periods; one that leaves more than a period after its period
        began is a missed period (counted), and a grid fallen further behind skips ahead."""
        s = self.settings
        period_ns = round(1e9 / s.servo_rate_hz)
        t_s = s.servo_period_s
        v = max(self._limits.velocity_max_rad_s)
        a = max(self._limits.acceleration_max_rad_s2)
        next_ns = time.monotonic_ns() + period_ns
        command, commands, servo = self._command, self.rings.commands, self.rings.servo
        failed = 0  # calls in a row that got no answer
        while True:
            wait_ns = next_ns - time.monotonic_ns()
            if self.conn.poll(max(wait_ns, 0) / 1e9):
                if self._message() == "stop":
                    return
                continue  # a request came before the period: wait on for it
            nominal_ns, next_ns = next_ns, next_ns + period_ns
            if self.faulted or not self.servoing:
                continue  # holding out of servo mode until the parent stops the session
            behind = (time.monotonic_ns() - nominal_ns) // period_ns
            if behind > 0:  # whole periods passed without a call: missed, and skipped
                self.servo_missed += behind
                nominal_ns += behind * period_ns
                next_ns = nominal_ns + period_ns
            newest_row(commands.rows, commands.header, command)
            row = command[0]
            if int(row["mode"]) == STOP:
                with contextlib.suppress(Exception):
                    self.motion.stopJoint(STOP_ACC_RAD_S2)
                self.servo_off()
                continue
            q = row["q"].tolist()
            sent_ns = time.monotonic_ns()
            self.servo_lateness.add(sent_ns - nominal_ns)
            try:
                code = int(self.motion.servoJoint(q, a, v, t_s, s.lookahead_s, s.gain))
                failed = 0
            except Exception as err:  # no answer within the request timeout, or a lost link
                code, failed = NO_ANSWER, failed + 1
                self.servo_failed += 1
                if failed >= MAX_FAILED_CALLS:
                    self.fault(f"servoJoint failed {failed} times in a row: {err}")
            done_ns = time.monotonic_ns()
            self.servo_calls += 1
            servo.push(sent_ns, done_ns, int(row["source_ns"]), code, int(row["mode"]), q)
            if code not in (0, NO_ANSWER) and not self.faulted:
                self.fault(self._refusal(code))
            if self.faulted:
                self.servo_off()

    def _refusal(self, code: int) -> str:
        """Why the controller refused a servoJoint: its safety or robot mode, asked now, in the
        words the RTDE stream's change would have (whichever comes first says the same), else
        servo mode left."""
        try:
            safety, robot = int(self.state.getSafetyModeType()), int(self.state.getRobotModeType())
        except Exception:  # the link is going: the code says what is known
            safety, robot = NORMAL, RUNNING
        if safety != NORMAL:
            name = SAFETY_NAMES.get(safety, str(safety))
            return f"the controller reports {name} (safety mode {safety})"
        if robot != RUNNING:
            return f"the robot left running (robot mode {robot})"
        return f"the controller refused servoJoint (code {code}): not in servo mode"

    def figures(self) -> dict[str, object]:
        """What the link did: RTDE samples, servoJoint calls, missed servo periods and the
        calls' lateness after their period's start (p50, p99, max in us)."""
        late = self.servo_lateness
        return {
            "rtde_samples": self.samples,
            "servo_calls": self.servo_calls,
            "servo_periods_missed": self.servo_missed,
            "servo_calls_unanswered": self.servo_failed,
            "servo_lateness_us": (late.quantile_us(0.5), late.quantile_us(0.99), late.max_ns / 1e3),
        }

    def _message(self) -> str:
        try:
            message = self.conn.recv()
        except (EOFError, OSError):
            return "stop"  # the parent is gone
        if message == "servo on":
            try:
                self.servo_on()
            except LinkFaultError as err:
                self.say("error-servo", str(err))
            else:
                self.say("servo", True)
        elif message == "servo off":
            self.servo_off()
            self.say("servo", False)
        return str(message)

    def close(self) -> None:
        self.servo_off()
        for client in (self.rtde, self.rpc):
            with contextlib.suppress(Exception):
                client.logout()
            with contextlib.suppress(Exception):
                client.disconnect()


def _log_in(client: Any, what: str, port: int, s: ArcsSettings) -> None:
    """Connect ``client`` (AUBO's RpcClient or RtdeClient) and log in; LinkFaultError says
    which step failed, with the client's code."""
    code = client.connect(s.host, port)
    if code != 0:
        raise LinkFaultError(f"{what} {s.host}:{port}: connect failed (code {code})")
    code = client.login(s.user, s.password)
    if code != 0:
        raise LinkFaultError(f"{what} login as {s.user!r} refused (code {code})")


def serve(conn: Connection, settings: ArcsSettings, specs: RingSpecs) -> None:
    """The child's entry (spawned by :class:`~hilrig.rig.arcs.link.ArcsLink`). Its threads run
    under SCHED_FIFO at :data:`LINK_PRIORITY` where permitted (AUBO's client's threads are made
    here, so they inherit it): between the loop's and the emulated rig's, since the servo
    stream carries the loop's commands to the arm (a busy machine starved it past the
    controller's servo timeout)."""
    raise_priority(LINK_PRIORITY)
    tighten_timer_slack()
    rings = Rings.attach(specs)
    link: _Link | None = None
    try:
        link = _Link(conn, settings, rings)
        try:
            info = link.connect()
        except LinkFaultError as err:
            report(conn, "error", f"{err}{_last_log(link)}")
            return
        except Exception as err:  # the client raises on timeouts and broken replies
            report(conn, "error", f"{type(err).__name__}: {err}{_last_log(link)}")
            return
        freeze_heap()  # no collector pass over the imports stops a servo period
        link.say("ready", info)
        link.serve()
    finally:
        if link is not None:
            link.close()
            link.say("done", link.figures())
        rings.close()


def _last_log(link: _Link) -> str:
    errors = [
        line
        for line in link.log
        if ("error" in line.lower() or "fail" in line.lower()) and "__login__" not in line
    ]
    return f" (client: {errors[-1]})" if errors else ""


@contextlib.contextmanager
def _stderr_muted() -> Iterator[None]:
    """This process's standard error (the descriptor: C++ writes there too) to /dev/null."""
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)
