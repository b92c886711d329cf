"""Emulated HIL sessions at 1 kHz with recording on: the loop's timing, measured three ways.

As ``hilrig record`` runs them: the emulated rig in its own process, the recorder in another,
the loop (its devices' I/O and the compiled tick on one thread) here. Five 60 s sessions:

- plain;
- with the live view on (``--view-url``: the recorder forwards its 50 Hz copy to the viewer-feed
  process, which streams it to Rerun's own gRPC server, ``rerun --save``, on loopback);
- while a busy process burns one of the two cores (a lab PC with a browser or viewer open);
- plain and beside the busy core again, with the kernel's unbound workers (``kworker/u*``,
  among them the one that hands a serial port's bytes to its reader) under SCHED_FIFO 1 for the
  session (those alive as its loop starts), as an operator's tuning would put them (tuned's
  scheduler plugin, or ``chrt``): hilrig does not change other threads' priorities itself
  (docs/rig-timing.md, "Placing the loop"). Skipped where not permitted (root or CAP_SYS_NICE).

The robot is driven as a real AUBO-i5 is: AUBO's client (pyaubo-sdk) in the ARCS link's
process streams ``servoJoint`` at 200 Hz over JSON-RPC and reads RTDE joint states at 500 Hz.
Reported for each: missed deadlines, tick lateness p50/p99/max, compute per tick p50/p99 (the
tick but for its send: compiled tick, events, row written), the targets' write to the link's
ring and the I/O before the tick (the links read, their rows stored), sensor-to-servoJoint (F/T
frame read -> the servoJoint call carrying targets computed from it leaves the link's process;
the call waits for its servo period, so up to 5 ms) and until it returned, the servo periods
missed (no call within a period), recorder drops, hold ticks, fallback ticks, the times the
nominal grid was found early and moved at once (:mod:`hilrig.rig.grid`), the emulated rig's own
slot lateness p99, its slots a period late and those it skipped (a rig that stopped over 5
periods skips its missed slots; its inputs then aged past the 5 ms hold limit, and the hold
ticks are the rig's, not the loop's), its CPU (its process's CPU time over the session's wall
time, from /proc), and the hypervisor's steal over the session (CPU time given to other
machines, which no priority here can win back). Each session starts once the machine is quiet
(:mod:`benchmarks.settle`: the suites before it leave these VMs slow to wake for a while), and
the wait is reported.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path

from benchmarks.harness import Result
from benchmarks.settle import settle
from hilrig.emulator.slots import MAX_BEHIND
from hilrig.machine import Steal
from hilrig.rig import ControlLoop, RigProcess, SessionConfig, SessionResult, record_session
from hilrig.rig.grid import FAST_SHIFT_NS, FAST_WINDOW
from hilrig.robot import aubo_i5_urdf
from hilrig.viz.live import LiveView
from hilrig.viz.save_server import rerun_save_server
from hilrig.viz.sinks import Sink, SinkKind

DURATION_S = 60.0
CLOCK_TICKS_S = os.sysconf("SC_CLK_TCK")


def run() -> list[Result]:
    tmp = Path(tempfile.mkdtemp(prefix="hilrig-bench-"))
    plain = _session(tmp / "session.mcap")
    with rerun_save_server(tmp / "live.rrd") as url:
        live = LiveView(
            Sink(SinkKind.CONNECT, url=url),
            session_id="bench",
            controller="adaptive",
            source="session-live.mcap",
            urdf=aubo_i5_urdf(),
        )
        viewed = _session(tmp / "session-live.mcap", live=live)
    with _busy_core():
        loaded = _session(tmp / "session-busy.mcap")
    results = (
        _timing(plain, "", missed_target=0.01)
        + _timing(viewed, " (live view)", missed_target=0.01)
        + _view(viewed)
        + _timing(loaded, " (a busy process on one core)", missed_target=0.1)
    )
    with _kernel_workers_at_fifo() as raised:  # tried and undone at once
        if not raised:
            return results
    tuned = _session(tmp / "session-tuned.mcap", tune_workers=True)
    with _busy_core():
        tuned_loaded = _session(tmp / "session-tuned-busy.mcap", tune_workers=True)
    return (
        results
        + _timing(tuned, " (kernel workers at FIFO 1)", missed_target=0.01)
        + _timing(
            tuned_loaded,
            " (a busy process on one core, kernel workers at FIFO 1)",
            missed_target=0.1,
        )
    )


class _Measured:
    """A session's result, its rig process's CPU share, the steal over it and the wait for a
    quiet machine before it."""

    def __init__(
        self, result: SessionResult, rig_cpu_pct: float, steal_pct: float, settled: Result
    ) -> None:
        self.result = result
        self.settled = settled
        self.rig_cpu_pct = rig_cpu_pct
        self.steal_pct = steal_pct


def _session(out: Path, live: LiveView | None = None, *, tune_workers: bool = False) -> _Measured:
    """A session; with ``tune_workers`` the kernel's workers are raised as its loop starts
    (the ones alive then: the kernel starts and ends them as their work comes and goes)."""
    settled = settle("session")
    rigs: list[RigProcess] = []
    tuning = contextlib.ExitStack()
    cpu: list[tuple[float, float]] = []  # (wall s, rig CPU s) at loop start and near its end
    steal: list[Steal] = []

    def sample() -> None:
        pid = rigs[0].pid
        assert pid is not None
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        cpu.append((time.monotonic(), (int(fields[11]) + int(fields[12])) / CLOCK_TICKS_S))

    def on_start(loop: ControlLoop) -> None:
        if tune_workers:
            tuning.enter_context(_kernel_workers_at_fifo())
        sample()
        steal.append(Steal())

        def near_the_end() -> None:
            time.sleep(DURATION_S - 1.0)  # the session's clock runs on; ticks may be merged
            sample()

        threading.Thread(target=near_the_end, daemon=True).start()

    with tuning:
        result = record_session(
            SessionConfig(
                out=out, subject_id="B001", scenario="hand-contact", duration_s=DURATION_S
            ),
            stop=threading.Event(),
            live=live,
            on_start=on_start,
            rig_ready=rigs.append,
        )
    (t0, c0), (t1, c1) = cpu[0], cpu[-1]
    return _Measured(result, 100 * (c1 - c0) / (t1 - t0), steal[0].percent(), settled)


@contextmanager
def _busy_core() -> Iterator[None]:
    """A process spinning on one core for as long as the block runs."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        busy.kill()
        busy.wait()


@contextmanager
def _kernel_workers_at_fifo() -> Iterator[list[int]]:
    """The kernel's unbound workers of normal priority (``kworker/u*`` at nice 0) under
    SCHED_FIFO 1, the lowest real-time priority, for as long as the block runs; yields their
    pids (none where not permitted). Workers the kernel starts meanwhile keep nice 0."""
    raised: list[int] = []
    try:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            pid = int(entry.name)
            try:
                if not (entry / "comm").read_text().startswith("kworker/u"):
                    continue
                if os.sched_getscheduler(pid) != os.SCHED_OTHER or os.getpriority(
                    os.PRIO_PROCESS, pid
                ):
                    continue
                os.sched_setscheduler(pid, os.SCHED_FIFO, os.sched_param(1))
            except PermissionError:
                break  # not permitted: none is raised
            except OSError:  # gone meanwhile
                continue
            raised.append(pid)
        yield raised
    finally:
        for pid in raised:
            with contextlib.suppress(OSError):
                os.sched_setscheduler(pid, os.SCHED_OTHER, os.sched_param(0))


def _timing(measured: _Measured, variant: str, *, missed_target: float) -> list[Result]:
    result = measured.result
    summary = result.summary
    late = summary.lateness.summary_us()
    s2c = summary.sensor_to_command.summary_us()
    s2a = summary.sensor_to_ack.summary_us()
    compute = summary.compute.summary_us()
    io = summary.io.summary_us()
    send = summary.send.summary_us()
    missed_pct = 100 * summary.missed_deadlines / summary.ticks
    rig = result.rig_counters
    nan = float("nan")
    rig_p99, rig_late, rig_skipped = (
        (nan,) * 3 if rig is None else (rig.slot_lateness_us[1], rig.slots_late, rig.slots_skipped)
    )
    detail = {
        "ticks": summary.ticks,
        "missed": summary.missed_deadlines,
        "fallback_ticks": summary.fallback_ticks,
        "hold_ticks": summary.hold_ticks,
        "lateness_us": late,
        "compute_us": compute,
        "io_us": io,
        "send_us": send,
        "sensor_to_command_us": s2c,
        "sensor_to_ack_us": s2a,
        "messages_written": result.messages_written,
        "drops": result.drops,
        "rig_cpu_pct": measured.rig_cpu_pct,
        "steal_pct": measured.steal_pct,
        "rig_counters": None if result.rig_counters is None else asdict(result.rig_counters),
        "robot_link": result.robot_link,
        "view": None if result.view is None else _view_counts(result),
    }

    def row(name: str, value: float, unit: str, target: str = "", ok: bool | None = None) -> Result:
        return Result("session", name + variant, value, unit, target, ok, detail)

    return [
        row(f"ticks ({DURATION_S:g} s at 1 kHz)", summary.ticks, "ticks"),
        row("missed deadlines", missed_pct, "%", f"<= {missed_target}",
            missed_pct <= missed_target),
        row("lateness p50", late["p50"], "us"),
        row("lateness p99", late["p99"], "us", "<= 100", late["p99"] <= 100),
        row("lateness max", late["max"], "us"),
        row("compute per tick p50", compute["p50"], "us"),
        row("compute per tick p99", compute["p99"], "us", "<= 50", compute["p99"] <= 50),
        row("targets' write to the robot link p50", send["p50"], "us"),
        row("targets' write to the robot link p99", send["p99"], "us"),
        row("I/O before a tick (links read, rows stored) p50", io["p50"], "us"),
        row("I/O before a tick p99", io["p99"], "us"),
        row("sensor-to-servoJoint p50", s2c["p50"], "us"),
        row("sensor-to-servoJoint p99", s2c["p99"], "us", "<= 1500", s2c["p99"] <= 1500),
        row("sensor-to-servoJoint returned p99", s2a["p99"], "us"),
        *_servo(result, row),
        row("recorder drops", result.drops, "rows", "== 0", result.drops == 0),
        row("hold ticks", summary.hold_ticks, "ticks", "== 0", summary.hold_ticks == 0),
        row("fallback ticks", summary.fallback_ticks, "ticks"),
        row("of the missed: periods whose frame came with the next (sent or read late)",
            summary.merged_frames, "periods"),
        row(f"grid found early and moved at once ({FAST_WINDOW} ticks in a row over "
            f"{FAST_SHIFT_NS // 1000} us late)", summary.grid_shifts, "times"),
        row("emulated sensor's own send lateness p99 (rig slots)", rig_p99, "us"),
        row("emulated rig's slots begun a period or more late", rig_late, "slots"),
        row(f"emulated rig's slots skipped (it stopped over {MAX_BEHIND} periods: its inputs "
            "aged past the hold limit)", rig_skipped, "slots"),
        row("emulated rig CPU", measured.rig_cpu_pct, "% of a core", "<= 25",
            measured.rig_cpu_pct <= 25),
        row("hypervisor steal over the session", measured.steal_pct, "% of CPU time"),
        replace(measured.settled, name=measured.settled.name + variant),
    ]  # fmt: skip


def _servo(result: SessionResult, row: Callable[..., Result]) -> list[Result]:
    """The ARCS link's servo stream: periods missed (no servoJoint left within its period of
    5 ms), the calls' lateness after their period's start, the RTDE joint states."""
    link = result.robot_link
    if "servo_calls" not in link:
        return []
    calls, missed = int(str(link["servo_calls"])), int(str(link["servo_periods_missed"]))
    late = link["servo_lateness_us"]
    assert isinstance(late, tuple | list)
    missed_pct = 100 * missed / max(calls + missed, 1)
    return [
        row("servoJoint calls (200 Hz)", calls, "calls"),
        row("servo periods missed", missed_pct, "%", "<= 0.1", missed_pct <= 0.1),
        row("servoJoint's lateness after its period's start p99", float(late[1]), "us"),
        row("RTDE joint states (500 Hz)", float(str(link["rtde_samples"])), "samples"),
    ]


def _view_counts(result: SessionResult) -> dict[str, object]:
    view = result.view
    assert view is not None
    return {
        "sent": view.sent,
        "dropped": view.dropped,
        "shown": view.shown,
        "problem": view.problem,
    }


def _view(measured: _Measured) -> list[Result]:
    view = measured.result.view
    assert view is not None
    detail = _view_counts(measured.result)
    return [
        Result("session", "live view batches sent", view.sent, "batches", "", None, detail),
        Result(
            "session",
            "live view batches dropped",
            view.dropped,
            "batches",
            "== 0",
            view.dropped == 0 and not view.problem,
            detail,
        ),
        Result("session", "live view batches shown", view.shown, "batches", "", None, detail),
    ]
