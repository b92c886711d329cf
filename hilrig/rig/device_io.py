"""The loop thread's side of the device links: wait on them, read them, record every sample.

:class:`DeviceIO` holds the wrist F/T sensor and the robot's link (its joint states and joint
targets, :mod:`.robot_port`: the Modbus pair or AUBO's ARCS interface), all polled (no driver
thread on the loop's side), and the recorder's feed. ``wait`` sleeps in
``select`` until one of them has data or a deadline passes; ``pump`` reads each without blocking
and puts every sample into its ring at once, from the first sample on (also while the session
tares and waits for the recorder, before the first tick). The drivers return their samples as
rows of the rings' own dtypes, which one compiled call a link stores in its shared ring (bound
to the driver's rows: ``Ring.feed_from``).
"""

from __future__ import annotations

import select
import time
from collections.abc import Callable
from dataclasses import dataclass

from hilrig.drivers.ft.link import FtSerial, SampleRows
from hilrig.rig.recorder_feed import RecorderFeed
from hilrig.rig.rings import Ring
from hilrig.rig.robot_port import JointStateSource, JointTargetSink


@dataclass
class DeviceIO:
    """The device links of a session and, when recording, the recorder's feed."""

    sensor: FtSerial
    robot: JointStateSource
    targets: JointTargetSink
    feed: RecorderFeed | None = None
    samples_read: int = 0  # wrist samples and joint states read so far
    watch_fds: tuple[int, ...] = ()  # files the wait watches beside the sensor ...
    watched: bool = False  # ... and whether the last wait found one readable

    def __post_init__(self) -> None:
        if self.feed is not None:  # a poll's rows: the first of its driver's rows
            self.feed.joint.feed_from(self.robot.rows)
            self.feed.ft.feed_from(self.sensor.rows)

    def wait(self, deadline_ns: int) -> int:
        """Sleep until the wrist sensor has data, one of ``watch_fds`` is readable (then
        ``watched``) or ``deadline_ns`` (monotonic); returns the time now. Only the sensor
        wakes the loop for data: the robot's state of its period arrives before it, and the
        robot link's replies are taken at the next tick, so one wake-up serves a period."""
        self.watched = False
        timeout_ns = deadline_ns - time.monotonic_ns()
        if timeout_ns > 0:
            fd, watch = self.sensor.fileno(), self.watch_fds
            ready = select.select([fd, *watch] if fd >= 0 else watch, [], [], timeout_ns / 1e9)[0]
            self.watched = bool(watch) and (len(ready) > 1 or (bool(ready) and ready[0] != fd))
        return time.monotonic_ns()

    def pump_until(
        self, done: Callable[[SampleRows], bool], give_up_ns: int, *, step_ns: int = 10_000_000
    ) -> bool:
        """Outside the loop: wait and read (every sample to the rings) until ``done(the wrist
        samples just read)`` is true, or ``give_up_ns`` passes (then False). ``done`` is asked
        at least every ``step_ns`` (the sensor may be silent)."""
        while True:
            now = self.wait(min(give_up_ns, time.monotonic_ns() + step_ns))
            if done(self.pump(now)):
                return True
            if now >= give_up_ns:
                return False

    def pump(self, now_ns: int) -> SampleRows:
        """Read every device without blocking and hand each sample to the recorder's rings;
        returns the wrist samples completed now, oldest first (the last is the newest)."""
        feed = self.feed
        states = self.robot.poll(now_ns)  # rows of the ring's own dtype
        if feed is not None and len(states):
            _store(feed.joint, states, self.robot.rows)  # one compiled call, drops counted
        self.targets.poll(now_ns)
        samples = self.sensor.poll(now_ns)
        self.samples_read += len(states) + len(samples)
        if feed is not None and len(samples):
            _store(feed.ft, samples, self.sensor.rows)  # rows of the ring's own dtype too
        return samples


def _store(ring: Ring, rows: SampleRows, driver_rows: SampleRows) -> None:
    """A poll's ``rows`` into ``ring``: by the call bound to the driver's rows when they are
    their first (every poll but the one after a connect)."""
    if rows.base is driver_rows:
        ring.put_first(len(rows))
    else:
        ring.put(rows)
