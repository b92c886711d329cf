"""The loop's side of an AUBO controller running ARCS: the joint states it reads and the joint
targets it writes, both through shared-memory rings to the link's process
(:mod:`.link_child`, where AUBO's own client runs).

:class:`ArcsLink` starts that process and asks it to enter servo mode and to stop;
:class:`ArcsJointStates` and :class:`ArcsTargets` are what the loop polls and writes, shaped as
the loop's other robot link (:mod:`hilrig.rig.robot_port`): no system call, no lock and nothing
allocated per tick. The targets leave at the servo rate, not the tick's: the link's process
sends the newest every servo period.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus
from hilrig.drivers.joint_targets.wire import Mode
from hilrig.drivers.robot_state.wire import STATE_DTYPE
from hilrig.errors import HilrigError, LinkError
from hilrig.rig.arcs.link_child import serve
from hilrig.rig.arcs.settings import ArcsSettings
from hilrig.rig.arcs.shared import NO_ANSWER, Rings, RingSpecs, take_rows
from hilrig.rig.child import ChildProcess
from hilrig.rig.records import SERVO_DTYPE
from hilrig.rig.rings import Ring

READY_TIMEOUT_S = 20.0
SERVO_TIMEOUT_S = 5.0
STOP_TIMEOUT_S = 5.0
POLL_ROWS = 64  # rows taken from a ring per poll at most (the rest at the next)


class ArcsLink:
    """The link's process: ``start()`` (connected, logged in, subscribed), ``servo_on()``,
    ``fault()`` (a line once the controller or the link failed), ``stop()``."""

    def __init__(self, settings: ArcsSettings) -> None:
        self.settings = settings
        self._child = ChildProcess(
            "hilrig-arcs-link", f"AUBO controller at {settings.where()}", LinkError
        )
        specs = RingSpecs.unique()
        self._specs = specs
        self.rings = Rings.create(specs)
        self.info: dict[str, object] = {}
        self.figures: dict[str, object] = {}  # what the link did, once stopped
        self._fault = ""

    def start(self) -> dict[str, object]:
        """Spawn the link and wait until it is connected, logged in and subscribed; raises
        LinkError with the controller's or the client's reason."""
        self._child.start(serve, (self.settings, self._specs))
        self.info = self._child.wait_report("ready", READY_TIMEOUT_S)
        return self.info

    def servo_on(self) -> None:
        """Enter servo mode (the controller checks its modes); raises LinkError if refused."""
        self._servo("servo on")

    def servo_off(self) -> None:
        """Leave servo mode; the joint states stream on. Raises LinkError if the link failed
        (its fault)."""
        if self._child.alive():
            self._servo("servo off")

    def _servo(self, request: str) -> None:
        self._child.send(request)
        while True:
            if not self._child.poll(SERVO_TIMEOUT_S):
                raise LinkError(f"{self._child.label}: {request} not confirmed in time")
            kind, value = self._receive()
            if kind == "servo":
                return
            if kind in ("error-servo", "fault"):
                raise LinkError(f"{self._child.label}: {value}")

    @property
    def fileno(self) -> int:
        """Readable once the link reports (a fault) or its process ends."""
        return self._child.fileno()

    def fault(self) -> str:
        """Why the link failed ("" while it is well): takes any report waiting."""
        while not self._fault and self._child.poll(0):
            kind, value = self._receive()
            if kind == "fault":
                self._fault = str(value)
        return self._fault

    def _receive(self) -> tuple[str, object]:
        kind, value = self._child.next_report()
        if kind == "ended":
            self._fault = self._fault or f"the link's process ended (code {value})"
            return "fault", self._fault
        return kind, value

    def stop(self) -> None:
        """Leave servo mode, log out, end the process (killed if it does not end in time);
        unlink the rings. Calling it again is harmless."""
        if self._child.started and self._child.alive():
            with contextlib.suppress(HilrigError):
                self._child.send("stop")
                while self._child.poll(STOP_TIMEOUT_S):
                    kind, value = self._receive()
                    if kind == "done" and isinstance(value, dict):
                        self.figures = value
                        break
                    if kind == "fault" and value == self._fault:
                        break
        self._child.stop(STOP_TIMEOUT_S)
        self._child.close()
        with contextlib.suppress(HilrigError):
            self.rings.close()


class ArcsJointStates:
    """The robot's joint states as RTDE delivered them (rows of STATE_DTYPE)."""

    def __init__(self, link: ArcsLink) -> None:
        self._ring = link.rings.states
        self.rows: NDArray[np.void] = np.zeros(POLL_ROWS, dtype=STATE_DTYPE)
        self.newest: NDArray[np.void] = np.zeros(1, dtype=STATE_DTYPE)
        self.samples = 0
        self._first_ns = 0  # the first state's receive time
        self.endpoint = f"rtde://{link.settings.host}:{link.settings.rtde_port}"

    def poll(self, now_ns: int) -> NDArray[np.void]:
        """The states received since the last poll, oldest first (rows the next poll reuses)."""
        ring = self._ring
        count = int(take_rows(ring.rows, ring.header, self.rows))
        if count:
            if not self.samples:
                self._first_ns = int(self.rows[0]["t_ns"])
            self.newest[0] = self.rows[count - 1]
            self.samples += count
        return self.rows[:count]

    def latest(self) -> np.void | None:
        return self.newest[0] if self.samples else None

    def fileno(self) -> int:
        return -1  # read at every tick: the sensor's frames wake the loop

    def status(self) -> LinkStatus:
        """The states' count, the newest one's age now and their rate since the first (the
        link's process keeps the connection: its faults come over its pipe, not here)."""
        if not self.samples:
            return LinkStatus(self.endpoint, True, 0, 0.0, None, 0, 0, 0, "")
        newest_ns = int(self.newest[0]["t_ns"])
        span_ns = newest_ns - self._first_ns
        rate_hz = (self.samples - 1) * 1e9 / span_ns if span_ns > 0 else 0.0
        age_ns = time.monotonic_ns() - newest_ns
        return LinkStatus(self.endpoint, True, self.samples, rate_hz, age_ns, 0, 0, 0, "")

    def close(self) -> None:
        """Nothing of its own: the link's process owns the connection."""


@dataclass
class ServoStats:
    """The servo stream's counts as the loop reads them (the writer's stats' names)."""

    sent: int = 0  # servoJoint calls made
    written: int = 0  # accepted (code 0)
    last_sent_ns: int = 0
    last_sent_source_ns: int = 0
    last_write_ns: int = 0
    last_source_ns: int = 0


class ArcsTargets:
    """Joint targets to the link's servo stream: every tick's into the commands ring."""

    def __init__(self, link: ArcsLink) -> None:
        self._commands = link.rings.commands
        self._servo = link.rings.servo
        self._rows: NDArray[np.void] = np.zeros(POLL_ROWS, dtype=SERVO_DTYPE)
        self.stats = ServoStats()
        self.errors = 0
        self.last_error = ""
        self.refused = 0  # targets not finite: never written
        self._record: Ring | None = None

    def record_into(self, ring: Ring) -> None:
        """Pass every servo call on to ``ring`` (the recorder's, rows of SERVO_DTYPE)."""
        self._record = ring

    def write(
        self, q_rad: NDArray[np.float64], mode: Mode = Mode.TRACK, *, source_ns: int = 0
    ) -> None:
        """The tick's targets for the next servo period (never blocks)."""
        if not np.isfinite(q_rad).all():
            self.refused += 1
            return
        slot = self._commands.reserve()
        if slot is None:
            return  # counted as the ring's drop: the link stopped taking them
        slot["t_ns"], slot["source_ns"], slot["mode"] = 0, source_ns, int(mode)
        slot["q"] = q_rad
        self._commands.commit()

    def poll(self, now_ns: int) -> None:
        """Take the servo calls made since the last poll into the counts."""
        ring = self._servo
        count = int(take_rows(ring.rows, ring.header, self._rows))
        if count and self._record is not None:
            self._record.put(self._rows[:count])  # one compiled call; a full ring counts drops
        stats = self.stats
        for i in range(count):
            row = self._rows[i]
            stats.sent += 1
            stats.last_sent_ns, stats.last_sent_source_ns = int(row["t_ns"]), int(row["source_ns"])
            code = int(row["code"])
            if code == 0:
                stats.written += 1
                stats.last_write_ns, stats.last_source_ns = (
                    int(row["done_ns"]),
                    stats.last_sent_source_ns,
                )
            else:
                self.errors += 1
                self.last_error = (
                    "servoJoint got no answer in time"
                    if code == NO_ANSWER
                    else f"servoJoint refused (code {code})"
                )

    def close(self) -> None:
        """Nothing of its own: the link's process owns the connection."""
