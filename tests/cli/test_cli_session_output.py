"""A session on the terminal: event lines thinned per source and second (the file keeps every
event), fault lines that say what they mean, and a summary that fits 80 columns, markup-free."""

import io
from pathlib import Path

from rich.console import Console

from hilrig.cli.session_output import EventLines, event_line, print_result
from hilrig.emulator.rig import RigCounters
from hilrig.recording.samples import EventKind, EventRecord
from hilrig.rig import LoopSummary, SessionResult
from hilrig.rig.events import EventDetector
from hilrig.rig.live_port import LiveReportLike


def clamp(t_ns: int) -> EventRecord:
    return EventRecord(t_ns, EventKind.FAULT, "safety", "clamp engaged: acceleration limit")


def test_at_most_five_lines_per_source_and_second_then_one_line_for_the_rest() -> None:
    lines = EventLines()
    printed: list[str] = []
    for i in range(100):  # 100 clamp engagements in the first second
        printed += lines.add(i / 100, clamp(i))
    stale = EventRecord(0, EventKind.FAULT, "wrist F/T sensor", "stale or lost")
    printed += lines.add(0.5, stale)  # another source has lines of its own
    assert len(printed) == 6
    assert printed[:2] == [
        "   0.00 s  fault: safety: clamp engaged: acceleration limit",
        "   0.01 s  fault: safety: clamp engaged: acceleration limit",
    ]
    assert printed[5] == "   0.50 s  fault: wrist F/T sensor: stale or lost"
    assert lines.due(0.99) == []  # the second is not over yet
    assert lines.due(1.0) == [
        "   1.00 s  ... 95 more safety events in the last second (all in /events)"
    ]
    assert lines.due(5.0) == []  # said once


def test_the_held_back_events_are_said_when_the_source_speaks_again_or_at_the_end() -> None:
    lines = EventLines(per_second=1)
    assert len(lines.add(0.1, clamp(1))) == 1
    assert lines.add(0.2, clamp(2)) == []
    assert lines.add(1.5, clamp(3)) == [
        "   1.00 s  ... 1 more safety event in the last second (all in /events)",
        "   1.50 s  fault: safety: clamp engaged: acceleration limit",
    ]
    assert lines.add(1.6, clamp(4)) == []
    assert lines.due() == ["   2.00 s  ... 1 more safety event in the last second (all in /events)"]


def test_a_stale_input_line_says_the_robot_holds_its_pose() -> None:
    events: list[EventRecord] = []
    detector = EventDetector(on_event=events.append)
    detector.link("wrist F/T sensor", False, 0)
    detector.clamp(4, 0)
    assert [event_line(7.33, e) for e in events] == [
        "   7.33 s  fault: wrist F/T sensor: stale or lost: the robot holds its pose until the "
        "data is fresh again",
        "   7.33 s  fault: safety: clamp engaged: acceleration limit (the commanded motion was "
        "limited to stay safe)",
    ]


class Live:
    sent, dropped, shown, problem = 604, 3, 601, ""


def result(path: Path, view: LiveReportLike | None = None) -> SessionResult:
    summary = LoopSummary(ticks=1_234_567, missed_deadlines=81_234, hold_ticks=136, ran_s=1234.5)
    for lateness_us in (135, 1060, 18_711):
        summary.lateness.add(lateness_us * 1000)
        summary.sensor_to_command.add(lateness_us * 1000)
        summary.sensor_to_ack.add((lateness_us + 1000) * 1000)
        summary.compute.add(lateness_us // 10 * 1000)
        summary.send.add(lateness_us // 100 * 1000)
    rig = RigCounters(*(10_000_000,) * 13, 321, slot_lateness_us=(43.0, 1337.0, 9999.0))
    return SessionResult(
        path,
        summary,
        8_765_432_109,
        12_345,
        [],
        recorder_error=f"recorder of {path}: exited with code -9; `hilrig recover {path} -o "
        "OUT` restores it",
        view=view,
        rig_counters=rig,
        ended_by="the recorder process died",
    )


def test_the_summary_fits_80_columns_keeps_every_number_and_reads_no_markup() -> None:
    path = Path("a[red]b.mcap")
    stream = io.StringIO()
    print_result(Console(file=stream, width=80, soft_wrap=True), result(path, Live()))
    lines = stream.getvalue().splitlines()
    assert lines[0] == "recorded a[red]b.mcap"
    assert lines[1:8] == [
        "  1234567 ticks, 81234 missed deadlines (6.580 %), 136 hold ticks",
        "  lateness p50 1060 us, p99 18711 us, max 18711 us",
        "  compute per tick p50 106 us, p99 1871 us; send p99 187 us",
        "  sensor to command sent p50 1060 us, p99 18711 us",
        "  sensor to command acknowledged p50 2060 us, p99 19711 us",
        "  8765432109 messages written, 12345 dropped; 0 events",
        "  ended early: the recorder process died at 1234.5 s; the robot was held",
    ]
    assert lines[8].startswith("  the file is incomplete: recorder of a[red]b.mcap: exited with")
    assert lines[9:] == [
        "  emulated rig: 10000000 F/T frames, 10000000 joint states sent",
        "  emulated rig's own slots late p50 43 us, p99 1337 us",
        "  emulated rig's slots skipped after stops of over 5 slots: 321",
        "  live view: 601 batches shown, 604 sent, 3 dropped",
    ]
    assert all(len(line) <= 80 for line in lines if "a[red]b.mcap" not in line)
