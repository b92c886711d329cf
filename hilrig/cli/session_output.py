"""A session on the terminal: its events as they come, a status line, and its summary."""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from typing import TYPE_CHECKING, TextIO

from rich.console import Console

if TYPE_CHECKING:
    from types import TracebackType

    from hilrig.recording.samples import EventRecord
    from hilrig.rig import ControlLoop, SessionResult

#: Seconds between two status lines.
STATUS_PERIOD_S = 0.5


class SessionWatch:
    """Prints a running session's events and, on a terminal, its status line twice a second,
    from a thread of its own: the session's callbacks (:meth:`on_start`, :meth:`on_event`, called
    from the loop) only store. Every event is printed, the last ones when the ``with`` ends."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.show_status = self.stream.isatty()
        self.started = time.monotonic()
        self.loop: ControlLoop | None = None
        self.pending: deque[tuple[float, EventRecord]] = deque()
        self.done = threading.Event()
        self.printer = threading.Thread(target=self._print, daemon=True, name="progress")

    def on_start(self, loop: ControlLoop) -> None:
        self.started = time.monotonic()
        self.loop = loop

    def on_event(self, record: EventRecord) -> None:
        self.pending.append((time.monotonic() - self.started, record))

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

    def _print(self) -> None:
        while True:
            finished = self.done.wait(STATUS_PERIOD_S)
            while self.pending:  # drained once more after the session: no event left unprinted
                t_s, record = self.pending.popleft()
                where = f" ({record.axis})" if record.axis else ""
                text = f"{t_s:7.2f} s  {record.kind.name.lower()}: {record.source}{where}"
                line = f"{text} {record.detail}".rstrip()
                self.stream.write(f"\r\033[K{line}\n" if self.show_status else f"{line}\n")
            if finished:
                return
            if self.show_status and self.loop is not None:
                self.stream.write(f"\r\033[K{status_line(self.loop, self.started)}")
            self.stream.flush()


def status_line(loop: ControlLoop, started: float) -> str:
    """One line: time, tick rate, lateness, force, offset, contact, hold reason, drops."""
    s = loop.status
    elapsed = max(time.monotonic() - started, 1e-9)
    line = (
        f"{elapsed:6.1f} s  {s.ticks / elapsed:6.0f} Hz  late {s.lateness_us:5.0f} us  "
        f"|f| {s.force_n:5.1f} N  |e| {s.offset_mm:5.1f} mm  {s.contact:10s}"
    )
    if s.holding:
        line += f"  HOLD ({s.holding})"
    if s.drops:
        line += f"  drops {s.drops}"
    return line


def print_result(console: Console, result: SessionResult) -> None:
    """The session's summary: file, ticks and timing, messages and drops, the emulated rig's
    own lateness and the live view's batches."""
    summary = result.summary
    late = summary.lateness.summary_us()
    s2c = summary.sensor_to_command.summary_us()
    ack = summary.sensor_to_ack.summary_us()
    missed_pct = 100 * summary.missed_deadlines / max(summary.ticks, 1)
    lines = [
        f"recorded {result.path}",
        f"  {summary.ticks} ticks, missed deadlines {summary.missed_deadlines} "
        f"({missed_pct:.3f} %), lateness p50 {late['p50']:.0f} us p99 {late['p99']:.0f} us "
        f"max {late['max']:.0f} us",
        f"  sensor-to-command (request sent) p50 {s2c['p50']:.0f} us p99 {s2c['p99']:.0f} us, "
        f"to its acknowledgement p50 {ack['p50']:.0f} us p99 {ack['p99']:.0f} us",
        f"  {result.messages_written or 'unknown'} messages written, {result.drops} dropped; "
        f"{len(result.events)} events, {result.summary.hold_ticks} hold ticks",
    ]
    rig = result.rig_counters
    if rig is not None:
        p50, p99, _ = rig.slot_lateness_us
        lines.append(
            f"  emulated rig: {rig.ft_frames_sent} F/T frames and {rig.joint_frames_sent} joint "
            f"states sent, its own slots late p50 {p50:.0f} us p99 {p99:.0f} us"
        )
    view = result.view
    if view is not None:
        line = f"  live view: {view.shown} batches shown, {view.sent} sent, {view.dropped} dropped"
        lines.append(line + (f"; {view.problem}" if view.problem else ""))
    for line in lines:
        console.print(line, highlight=False)
