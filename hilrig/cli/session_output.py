"""A session on the terminal: its events as they come (a few per second and source at most), a
status line, and its summary in lines that fit 80 columns."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, TextIO

from rich.console import Console

if TYPE_CHECKING:
    from types import TracebackType

    from hilrig.recording.samples import EventRecord
    from hilrig.rig import ControlLoop, SessionResult
    from hilrig.rig.write_failure import WriteFailure

#: Seconds between two status lines.
STATUS_PERIOD_S = 0.5
#: Event lines per source in one second of the session; the rest are counted in one line.
LINES_PER_SOURCE_S = 5


@dataclass
class _Window:
    """One source's events in one second of the session: lines shown and events held back."""

    second: int
    shown: int = 0
    held: int = 0


class EventLines:
    """The console's lines for a session's events: at most ``per_second`` lines per source in
    each second of session time; the others of that second are said in one line once it is over
    (``... 12 more safety events in the last second (all in /events)``). The file keeps every
    event: only the console is thinned."""

    def __init__(self, per_second: int = LINES_PER_SOURCE_S) -> None:
        self.per_second = per_second
        self.windows: dict[str, _Window] = {}

    def add(self, t_s: float, record: EventRecord) -> list[str]:
        """The lines to print for ``record``, at ``t_s`` s into the session (none if held)."""
        second = math.floor(t_s)
        window = self.windows.get(record.source)
        lines = []
        if window is None or window.second != second:
            if window is not None:
                lines += self._held_line(record.source, window)
            window = self.windows[record.source] = _Window(second)
        if window.shown < self.per_second:
            window.shown += 1
            lines.append(event_line(t_s, record))
        else:
            window.held += 1
        return lines

    def due(self, now_s: float = math.inf) -> list[str]:
        """The lines of held-back events whose second ended before ``now_s`` (all by default)."""
        lines = []
        for source, window in self.windows.items():
            if window.second + 1 <= now_s:
                lines += self._held_line(source, window)
        return lines

    @staticmethod
    def _held_line(source: str, window: _Window) -> list[str]:
        held, window.held = window.held, 0
        if not held:
            return []
        noun = "event" if held == 1 else "events"
        return [
            f"{window.second + 1:7.2f} s  ... {held} more {source} {noun} in the last second "
            "(all in /events)"
        ]


def event_line(t_s: float, record: EventRecord) -> str:
    """``   4.02 s  collision start: controller (end effector)``, one line."""
    kind = record.kind.name.lower().replace("_", " ")
    where = f" ({record.axis})" if record.axis else ""
    detail = f": {record.detail}" if record.detail else ""
    return f"{t_s:7.2f} s  {kind}: {record.source}{where}{detail}".replace("\n", " ")


class SessionWatch:
    """Prints a running session's events (:class:`EventLines`) and, on a terminal, its status
    line twice a second, from a thread of its own: the session's callbacks (:meth:`on_start`,
    :meth:`on_event`, called from the loop) only store. The last lines are printed when the
    ``with`` ends."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.show_status = self.stream.isatty()
        self.started_ns = time.monotonic_ns()
        self.loop: ControlLoop | None = None
        self.pending: deque[EventRecord] = deque()
        self.lines = EventLines()
        self.done = threading.Event()
        self.printer = threading.Thread(target=self._print, daemon=True, name="progress")

    def on_start(self, loop: ControlLoop) -> None:
        self.started_ns = time.monotonic_ns()
        self.loop = loop

    def on_event(self, record: EventRecord) -> None:
        self.pending.append(record)

    def __enter__(self) -> SessionWatch:
        self.printer.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.done.set()
        self.printer.join(timeout=2)
        if self.show_status:
            self.stream.write("\r\033[K")
            self.stream.flush()

    def _print(self) -> None:
        while True:
            finished = self.done.wait(STATUS_PERIOD_S)
            lines = []
            while self.pending:  # drained once more after the session: no event left unsaid
                record = self.pending.popleft()
                lines += self.lines.add((record.t_ns - self.started_ns) / 1e9, record)
            now_s = math.inf if finished else (time.monotonic_ns() - self.started_ns) / 1e9
            lines += self.lines.due(now_s)
            for line in lines:
                self.stream.write(f"\r\033[K{line}\n" if self.show_status else f"{line}\n")
            if finished:
                self.stream.flush()
                return
            if self.show_status and self.loop is not None:
                self.stream.write(f"\r\033[K{status_line(self.loop, self.started_ns)}")
            self.stream.flush()


def status_line(loop: ControlLoop, started_ns: int) -> str:
    """One line: time, tick rate, lateness, force, offset, contact, hold reason, drops."""
    s = loop.status()
    elapsed = max((time.monotonic_ns() - started_ns) / 1e9, 1e-9)
    line = (
        f"{elapsed:6.1f} s  {s.ticks / elapsed:6.0f} Hz  late {s.lateness_us:5.0f} us  "
        f"|f| {s.force_n:5.1f} N  |e| {s.offset_mm:5.1f} mm  {s.contact:10s}"
    )
    if s.holding:
        line += f"  HOLD ({s.holding})"
    if s.drops:
        line += f"  drops {s.drops}"
    return line


def summary_console() -> Console:
    """stdout for summaries: lines never wrapped by rich, user text never read as markup."""
    return Console(soft_wrap=True, markup=False, highlight=False)


def print_verdict(console: Console, result: SessionResult) -> None:
    """The recorded collisions' safety verdict in one line (``hilrig analyze`` has the table);
    nothing when the file cannot be read back whole."""
    from hilrig.analysis import analyze, load_session
    from hilrig.analysis.report import verdict_line
    from hilrig.errors import HilrigError

    if result.recorder_error:
        return
    try:
        console.print(verdict_line(analyze(load_session(result.path))), soft_wrap=True)
    except HilrigError as err:
        console.print(f"safety: not judged ({err})", soft_wrap=True)


def print_result(console: Console, result: SessionResult) -> None:
    """The session's summary, each line within 80 columns (but the file's name): file, ticks
    and timing, messages and drops, how it ended, the emulated rig's own lateness and skipped
    slots, and the live view's batches."""
    from hilrig.emulator.slots import MAX_BEHIND

    summary = result.summary
    late = summary.lateness.summary_us()
    s2c = summary.sensor_to_command.summary_us()
    ack = summary.sensor_to_ack.summary_us()
    compute, send = summary.compute.summary_us(), summary.send.summary_us()
    missed_pct = 100 * summary.missed_deadlines / max(summary.ticks, 1)
    written = (
        "messages written: not counted (the recorder did not close the file)"
        if result.messages_written is None
        else f"{result.messages_written} messages written"
    )
    lines = [
        f"recorded {result.path}",
        f"  {summary.ticks} ticks, {summary.missed_deadlines} missed deadlines "
        f"({missed_pct:.3f} %), {summary.hold_ticks} hold ticks",
        f"  lateness p50 {late['p50']:.0f} us, p99 {late['p99']:.0f} us, max {late['max']:.0f} us",
        f"  compute per tick p50 {compute['p50']:.0f} us, p99 {compute['p99']:.0f} us;"
        f" send p99 {send['p99']:.0f} us",
        f"  sensor to command sent p50 {s2c['p50']:.0f} us, p99 {s2c['p99']:.0f} us",
        f"  sensor to command acknowledged p50 {ack['p50']:.0f} us, p99 {ack['p99']:.0f} us",
        f"  {written}, {result.drops} dropped; {len(result.events)} events",
    ]
    lines += _robot_link_lines(result.robot_link)
    lines.append(ended_line(result))
    if result.recorder_error:
        lines.append(f"  the file is incomplete: {result.recorder_error}")
    rig = result.rig_counters
    if rig is not None:
        p50, p99, _ = rig.slot_lateness_us
        states = rig.rtde_samples_sent or rig.joint_frames_sent
        lines += [
            f"  emulated rig: {rig.ft_frames_sent} F/T frames, {states} joint states sent",
            f"  emulated rig's own slots late p50 {p50:.0f} us, p99 {p99:.0f} us",
            # a stop of the rig over the staleness limit holds the robot: the rig's, not the loop's
            f"  emulated rig's slots skipped after stops of over {MAX_BEHIND} slots: "
            f"{rig.slots_skipped}",
        ]
    view = result.view
    if view is not None:
        line = f"  live view: {view.shown} batches shown, {view.sent} sent, {view.dropped} dropped"
        lines.append(line + (f"; {view.problem}" if view.problem else ""))
    for line in lines:
        console.print(line, markup=False, highlight=False)


def ended_line(result: SessionResult) -> str:
    """``  ended: duration reached (20.0 s)``, or ``  ended early: <why> at 3.2 s; the robot
    was held`` (an interrupt, a fault, a disk that refused a write)."""
    from hilrig.recording.outcome import DURATION_REACHED, ran_its_course

    ran_s = result.summary.ran_s
    if ran_its_course(result.ended_by):
        return f"  ended: {DURATION_REACHED} ({ran_s:.1f} s)"
    return f"  ended early: {result.ended_by} at {ran_s:.1f} s; the robot was held"


def disk_failure_line(result: SessionResult, failure: WriteFailure, duration_s: float) -> str:
    """``hilrig record``'s one line for a write its disk refused: what failed, when, how much of
    the session the file keeps (its whole chunks) and what to do."""
    kept_s = max(0.0, (failure.kept_until_ns - result.summary.start_ns) / 1e9)
    path = result.path
    return (
        f"{failure.problem}: the recording stopped at {result.summary.ran_s:.1f} s of"
        f" {duration_s:g} s; {kept_s:.1f} s kept in {path}, cut at its last whole chunk"
        f" (`hilrig recover {path} -o OUT` makes it whole); {failure.remedy}"
    )


def _robot_link_lines(link: dict[str, object]) -> list[str]:
    """The ARCS link's servo stream and joint states (none for the Modbus pair)."""
    if link.get("robot_link") != "arcs" or "servo_calls" not in link:
        return []
    calls, missed = link["servo_calls"], link["servo_periods_missed"]
    late = link["servo_lateness_us"]
    assert isinstance(calls, int) and isinstance(missed, int) and isinstance(late, tuple | list)
    share = 100 * missed / max(calls + missed, 1)
    return [
        f"  servoJoint: {calls} calls at {link['servo_rate_hz']} Hz, {missed} periods missed "
        f"({share:.3f} %), late p99 {late[1]:.0f} us",
        f"  RTDE: {link['rtde_samples']} joint states at {link['rtde_rate_hz']} Hz",
    ]
