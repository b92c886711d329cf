"""The real-time loop: one thread does the devices' I/O and the tick, triggered by the sensor.

The loop's thread owns the wrist sensor's link and polls the robot's (no driver thread competes
with it for the GIL): it sleeps in ``select`` on the sensor's serial port; whatever arrives is
read without blocking and every sample goes to the recorder's rings at once. The robot's link
(:mod:`.robot_port`) is polled at every tick: AUBO's ARCS interface through shared-memory rings
to its own process, or the Modbus pair on sockets. A completed wrist F/T frame starts a tick
(sensor-triggered), so the command leaves within the period in which its sample arrived; if no
frame comes for a whole period past the expected one, a fallback tick runs on the deadline (it
will hold once inputs are stale).

One tick (docs/rig.md, the path of a force sample): the newest wrist sample and joint state go
through the compiled tick (:mod:`hilrig.tick.kernel`: compensation, base frame, 9-axis controller,
IK, joint offsets, safety clamp), the joint targets go to the robot's link without waiting (over
ARCS the link's servo stream sends the newest at the servo rate), and the tick row is written
into the ring in place. Stale sensor data, a lost robot link or a failed write hold the last
safe pose (a controlled stop); a force above the protective limit stops the robot (mode STOP,
latched).

Timing. Ticks sit on a grid of nominal times one period apart that follows the sensor's clock
(:mod:`.grid`). A tick's lateness is its start (the wake-up) minus its nominal time; a missed
deadline is a tick whose work ended more than one period after its nominal time.

A frame ``NUDGE_NS`` overdue is asked for: the loop wakes and reads every link, readable or not.
A serial port's bytes reach the reader through the kernel's tty buffer, which a kernel worker of
normal priority hands on; a read of the port makes the kernel hand on what it holds first. That
worker can wait a whole period behind another thread of normal priority (traced here: the
kernel's DAMON thread), and the frame would then come with the next one (docs/rig-timing.md).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hilrig.control import (
    AdmittanceController,
    Law,
    ParamsLike,
    combine,
    make,
    parse_law,
    resolve_params,
)
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.drivers.joint_targets.wire import Mode
from hilrig.errors import HilrigError
from hilrig.recording.outcome import DURATION_REACHED
from hilrig.recording.samples import ContactState, EventRecord
from hilrig.rig.device_io import DeviceIO
from hilrig.rig.events import EventDetector
from hilrig.rig.grid import NominalGrid
from hilrig.rig.loop_figures import LoopStatus, LoopSummary
from hilrig.rig.stop import stop_reason
from hilrig.rig.virtual import VirtualInput
from hilrig.robot import RobotModel
from hilrig.tick.kernel import CONTACT_CHANGED, FRESH, HELD, STOP_NOW, CompiledTick, TickInputs
from hilrig.tick.links import COMMAND_FAULT_HOLD_NS, COMMAND_LINK, ROBOT_LINK, SENSOR_LINK
from hilrig.tick.loop_step import (
    CLAMP_CHANGED,
    HOLD_UNTIL_NS,
    IS_STOPPED,
    REPORT,
    ROBOT_CHANGED,
    ROBOT_IS_OK,
    SENSOR_CHANGED,
    SENSOR_IS_OK,
    loop_words,
)
from hilrig.tick.safety import SafetyClamp
from hilrig.tick.trajectory import Trajectory
from hilrig.tick.trajectory_kernel import desired_writer
from hilrig.timing import realtime_python

# A frame this late past its period is asked for: a read hands over what the tty's worker holds
NUDGE_NS = 200_000


@dataclass(frozen=True)
class Watchdog:
    """What ends a session early: ``reason()`` names why ("" for nothing). It is asked only
    when one of ``fds`` is readable, which the loop's wait watches beside the sensor (e.g. a
    child process's sentinel, readable once the process has ended, or the robot link's pipe),
    so no tick pays for asking."""

    fds: tuple[int, ...]
    reason: Callable[[], str]


@dataclass(frozen=True)
class LoopConfig:
    """What the loop runs: rate (Hz), law and parameters of each axis group, staleness limit,
    and the CPU its thread runs on alone (None: wherever the OS puts it; docs/rig-timing.md)."""

    rate_hz: float = 1000.0
    law: Law = Law.ADAPTIVE
    cartesian_params: ParamsLike = "adaptive"
    joint_params: ParamsLike = "adaptive-joint"
    stale_after_ticks: int = 5
    cpu: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 1.0 <= self.rate_hz <= 10_000.0):
            raise HilrigError(f"loop rate {self.rate_hz} Hz is not within 1..10000 Hz")
        cpu = self.cpu
        if cpu is not None and (isinstance(cpu, bool) or not isinstance(cpu, int) or cpu < 0):
            raise HilrigError(f"cpu {self.cpu}: must be a CPU's number, 0 or more")
        object.__setattr__(self, "law", parse_law(self.law))

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.rate_hz)

    def controller(self) -> AdmittanceController:
        """The 9-axis controller (Cartesian group, joint group); raises ParameterError."""
        params = combine(
            (resolve_params(self.cartesian_params), 3), (resolve_params(self.joint_params), 6)
        )
        return make(self.law, params, dt=1.0 / self.rate_hz)

    def params_record(self) -> dict[str, Any]:
        """The parameters as plain values, for the session metadata."""
        params = self.controller().params
        return {
            "law": self.law.value,
            "rate_hz": self.rate_hz,
            **{k: str(v) for k, v in params.__dict__.items() if v is not None},
        }


class ControlLoop:
    """The tick on the thread that does the devices' I/O (``io``, connected before ``run``)."""

    def __init__(
        self,
        config: LoopConfig,
        *,
        io: DeviceIO,
        compensator: GravityCompensator,
        trajectory: Trajectory,
        safety: SafetyClamp,
        model: RobotModel,
        on_event: Callable[[EventRecord], None] | None = None,
        virtual: VirtualInput | None = None,
        watchdog: Watchdog | None = None,
        robot_period_ns: int | None = None,
    ) -> None:
        self.config = config
        self._watchdog = watchdog
        if watchdog is not None:
            io.watch_fds = watchdog.fds
        self._io = io
        self._sensor = io.sensor
        self._robot = io.robot
        self._targets = targets = io.targets
        self._feed = io.feed
        self._on_event = on_event
        self._virtual = virtual
        self._events = EventDetector(on_event=self._event)
        self._controller = config.controller()
        latest = self._robot.latest()
        if latest is None:
            raise HilrigError("the control loop needs a robot state: connect the robot first")
        q0 = np.array(latest["q"], dtype=np.float64)
        # the kernel reads the newest samples in place: views their drivers keep current
        newest_state, newest_sample = self._robot.newest, self._sensor.newest
        measured = TickInputs(
            raw_wrench=newest_sample["wrench"][0],
            q_measured=newest_state["q"][0],
            torque_measured=newest_state["tau"][0],
        )
        self._kernel = CompiledTick.build(
            self._controller, model, safety, compensator, q0, 1.0 / config.rate_hz, measured
        )
        self.summary = LoopSummary()
        self.holding = ""  # why the robot holds ("" if it tracks), set by every tick
        self._period_ns = config.period_ns
        self._stale_ns = config.stale_after_ticks * config.period_ns
        # the robot's states come at its own rate (RTDE's, or every tick): as many of its
        # periods make it stale
        robot_stale_ns = max(self._stale_ns, config.stale_after_ticks * (robot_period_ns or 0))
        # the loop's settings and last states, compiled
        self._words = loop_words(self._stale_ns, robot_stale_ns)
        self._step = self._kernel.loop_step(newest_sample, newest_state, self._words)
        self._inputs = inputs = self._kernel.inputs
        inputs.rotation_d[:] = trajectory.rotation  # the task keeps the start orientation
        inputs.orientation_d[:] = trajectory.orientation
        self._desired = desired_writer(trajectory, inputs.position_d)  # compiled: one call a tick
        self._q_cmd = self._kernel.q_cmd
        self._put_row: Callable[..., bool] | None = None  # bound to the ring while running
        self._send_ns = 0
        self._command_errors = targets.errors
        self._sent = targets.stats.sent
        self._acknowledged = targets.stats.written
        self._playing = False
        self._t0_ns = 0
        self._task_ticks, self._task_dt_s = 0, 1.0 / config.rate_hz
        self._last_start_ns = 0
        self._last_nominal_ns = 0
        self.ended_by = ""  # how run() ended (outcome.py): duration, stop's reason, watchdog

    def _event(self, record: EventRecord) -> None:
        if self._feed is not None:
            self._feed.event(record)
        if self._on_event is not None:
            self._on_event(record)

    # -- the loop -----------------------------------------------------------------------------

    def run(self, duration_s: float | None, stop: threading.Event) -> LoopSummary:
        """Tick until ``duration_s`` has passed, ``stop`` is set or the watchdog (asked when
        its fd is readable) names a reason to end, said by :attr:`ended_by`; returns the
        summary. The robot is left holding."""
        feed = self._feed
        if feed is not None:  # bound to the ring's rows while running, released after
            self._put_row = self._kernel.row_writer(feed.tick.rows, feed.tick.header, feed.headers)
        try:
            self._ticks(duration_s, stop)
        finally:
            self._put_row = None
        self._targets.write(self._q_cmd, Mode.HOLD)
        return self.summary

    def _ticks(self, duration_s: float | None, stop: threading.Event) -> None:
        period = self._period_ns
        summary = self.summary
        add_period = summary.period_adder()
        self._events.mark("loop", "session started at the start pose", time.monotonic_ns())
        # first: its one garbage collection must not delay tick 1
        with realtime_python(self.config.cpu):
            # what came while the loop started is recorded, not ticked: tick 1 is the next frame
            self._io.pump(time.monotonic_ns())
            now = time.monotonic_ns()
            self._t0_ns = now
            end_ns = None if duration_s is None else now + round(duration_s * 1e9)
            # the loop's start anchors the grid until a frame re-anchors it: a sensor silent
            # from the start still gets fallback ticks (holding) and the session still ends
            grid = NominalGrid(period, now)
            summary.start_ns = now
            while not stop.is_set():
                last = grid.nominal_ns
                wake_ns = last + period + NUDGE_NS  # then read even if nothing is readable
                if time.monotonic_ns() >= wake_ns:
                    wake_ns = last + 2 * period  # the fallback tick's deadline
                now = self._io.wait(wake_ns)
                frames = len(self._io.pump(now))
                if frames:  # each frame is one period of the sensor's clock
                    summary.merged_frames += frames - 1
                elif now < last + 2 * period:
                    continue  # no frame yet, and a whole period not yet past: wait on
                nominal = grid.place(now, frames)
                lateness = now - nominal
                if end_ns is not None and nominal >= end_ns:
                    self.ended_by = DURATION_REACHED
                    break
                if not frames:
                    summary.fallback_ticks += 1
                ticking = time.monotonic_ns()
                self.tick(now, nominal)
                if self._io.watched and self._watchdog is not None:
                    reason = self._watchdog.reason()
                    if reason:  # e.g. the recorder died: nothing would be recorded any more
                        self.ended_by = reason
                        self._events.fault("session", f"{reason}: robot held, session ended", now)
                        break
                done = time.monotonic_ns()
                send_ns = self._send_ns
                add_period(ticking - now, done - ticking - send_ns, send_ns, lateness)
                if done - nominal > period:
                    summary.missed_deadlines += 1
                summary.missed_deadlines += frames - 1 if frames else 0
            summary.grid_shifts = grid.fast_shifts
            summary.ran_s = (self._last_nominal_ns - self._t0_ns) / 1e9 if summary.ticks else 0.0
            self.ended_by = self.ended_by or stop_reason(stop)

    def tick(self, start_ns: int, nominal_ns: int) -> None:
        """One tick on the newest samples, started at ``start_ns`` for ``nominal_ns``."""
        targets = self._targets
        if targets.errors != self._command_errors:  # a refused write, a timeout or a lost link
            self._command_errors = targets.errors
            self._words[HOLD_UNTIL_NS] = start_ns + COMMAND_FAULT_HOLD_NS
            self._events.fault(COMMAND_LINK, str(targets.last_error), start_ns)
        # the task advances one period a tick, as the controller and the clamp count time: a
        # late tick or frames read together slow it down instead of making it jump (a jump
        # is a step the clamp cuts at its acceleration limit, docs/rig.md)
        self._task_ticks += 1
        self._desired(self._task_ticks * self._task_dt_s)
        if self._virtual is not None:
            self._play((nominal_ns - self._t0_ns) / 1e9, nominal_ns)
        # freshness, flags, the compiled tick and what changed, in one call (tick/loop_step.py)
        result = self._step(start_ns)
        fresh = result & FRESH and not result & HELD
        sending = time.monotonic_ns()
        targets.write(
            self._q_cmd,
            Mode.STOP if result & IS_STOPPED else Mode.TRACK,
            source_ns=self._sensor.latest_t_ns if fresh else 0,
        )
        self._send_ns = time.monotonic_ns() - sending
        if result & REPORT:
            self._report(result, start_ns)
        self._track_latency()
        if result & HELD:
            self.summary.hold_ticks += 1
            self.holding = (
                "stopped"
                if result & IS_STOPPED
                else ("command fault" if result & FRESH else "stale input")
            )
        else:
            self.holding = ""
        self._log_tick(start_ns, nominal_ns)

    def _report(self, result: int, t_ns: int) -> None:
        """The events of a tick whose result says something changed."""
        events = self._events
        if result & SENSOR_CHANGED:
            events.link(SENSOR_LINK, bool(result & SENSOR_IS_OK), t_ns)
        if result & ROBOT_CHANGED:
            events.link(ROBOT_LINK, bool(result & ROBOT_IS_OK), t_ns)
        if result & CONTACT_CHANGED:
            events.contact(self._controller.contact, t_ns)
        if result & STOP_NOW:
            force = self._kernel.force
            events.fault(
                "safety",
                "protective limit: robot stopped",
                t_ns,
                value=math.hypot(force[0], force[1], force[2]),
            )
        if result & CLAMP_CHANGED:
            events.clamp(result & 0xFF, t_ns)

    def _play(self, t_s: float, t_ns: int) -> None:
        """This tick's row of the virtual collision into the extra input; mark start and end."""
        assert self._virtual is not None
        extra = self._inputs.extra
        extra[:] = 0.0
        playing = self._virtual.add_to(t_s, extra)
        if playing != self._playing:
            self._playing = playing
            what = "started" if playing else "ended"
            self._events.mark("virtual collision", f"playback {what}", t_ns)

    def _track_latency(self) -> None:
        """Sensor-to-command (request sent) and sensor-to-acknowledgement of fresh commands."""
        stats = self._targets.stats
        summary = self.summary
        if stats.sent != self._sent:
            self._sent = stats.sent
            if stats.last_sent_source_ns:
                summary.sensor_to_command.add(stats.last_sent_ns - stats.last_sent_source_ns)
        if stats.written != self._acknowledged:
            self._acknowledged = stats.written
            if stats.last_source_ns:
                summary.sensor_to_ack.add(stats.last_write_ns - stats.last_source_ns)

    def _log_tick(self, start_ns: int, nominal_ns: int) -> None:
        summary = self.summary
        summary.ticks += 1
        feed = self._feed
        if feed is not None and self._put_row is not None:  # reserved, filled, published
            last = self._last_start_ns
            self._put_row(
                start_ns,
                summary.ticks,
                start_ns - last if last else 0,
                time.monotonic_ns() - start_ns,
                start_ns - nominal_ns,
                summary.missed_deadlines,
            )
        self._last_start_ns = start_ns
        self._last_nominal_ns = nominal_ns

    def status(self) -> LoopStatus:
        """The status line's values now, read from the loop's own figures and arrays: for
        another thread at a display's rate, so that the tick does no work for it (a value may
        be a tick newer than another)."""
        force, offset = self._kernel.force, self._controller.offset
        groups = [ContactState(code) for code in self._controller.contact]
        engaged = [state for state in groups if state != ContactState.FREE]
        return LoopStatus(
            ticks=self.summary.ticks,
            lateness_us=(self._last_start_ns - self._last_nominal_ns) / 1000,
            force_n=math.hypot(force[0], force[1], force[2]),
            offset_mm=1000 * math.hypot(offset[0], offset[1], offset[2]),
            contact=(engaged or groups)[0].name.lower(),
            holding=self.holding,
            drops=0 if self._feed is None else self._feed.drops,
            stopped=self._kernel.stopped,
        )
