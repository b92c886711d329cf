"""Emulated HIL sessions at 1 kHz with recording on, without and with the live view: the loop's
timing, measured.

The emulated rig runs in its own process, the recorder in another, the loop here, as
``hilrig record`` runs them; with the live view (``--view-url``) the recorder forwards its
50 Hz copy to the viewer-feed process, which streams it to Rerun's own gRPC server
(``rerun --save``, no window) on loopback. Reported for each: tick lateness p50/p99/max, missed
deadlines (ticks whose work ended after the next deadline), compute per tick and
sensor-to-command latency (F/T frame arrival -> the Modbus write of the joint targets computed
from it acknowledged), p50/p99; with the view, its batches sent, dropped and shown.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path

from benchmarks.harness import Result
from hilrig.rig import SessionConfig, SessionResult, record_session
from hilrig.viz.sinks import Sink, SinkKind, grpc_url, rerun_binary

DURATION_S = 30.0


def run() -> list[Result]:
    tmp = Path(tempfile.mkdtemp(prefix="hilrig-bench-"))
    off = _session(tmp / "session.mcap", None)
    with _rerun_server(tmp / "live.rrd") as url:
        on = _session(tmp / "session-live.mcap", Sink(SinkKind.CONNECT, url=url))
    return _timing(off, "") + _timing(on, " (live view)") + _view(on)


def _session(out: Path, view: Sink | None) -> SessionResult:
    return record_session(
        SessionConfig(
            out=out, subject_id="B001", scenario="hand-contact", duration_s=DURATION_S, view=view
        ),
        stop=threading.Event(),
    )


@contextmanager
def _rerun_server(saved: Path) -> Iterator[str]:
    """Rerun's gRPC server saving what it receives to ``saved``, on a free loopback port; its
    URL."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = subprocess.Popen(
        [str(rerun_binary()), "--save", str(saved), "--port", str(port), "--bind", "127.0.0.1"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 30
        while socket.socket().connect_ex(("127.0.0.1", port)) != 0:
            if time.monotonic() > deadline or server.poll() is not None:
                raise RuntimeError(f"rerun --save did not listen on port {port}")
            time.sleep(0.05)
        yield grpc_url(port)
    finally:
        server.send_signal(signal.SIGINT)  # it stops saving and exits
        server.wait(30)


def _timing(result: SessionResult, variant: str) -> list[Result]:
    summary = result.summary
    late = summary.lateness.summary_us()
    s2c = summary.sensor_to_command.summary_us()
    compute = summary.compute.summary_us()
    missed_pct = 100 * summary.missed_deadlines / summary.ticks
    detail = {
        "ticks": summary.ticks,
        "missed": summary.missed_deadlines,
        "skipped": summary.skipped_ticks,
        "hold_ticks": summary.hold_ticks,
        "lateness_us": late,
        "compute_us": compute,
        "sensor_to_command_us": s2c,
        "messages_written": result.messages_written,
        "drops": result.drops,
        "view": None if result.view is None else asdict(result.view),
    }

    def row(name: str, value: float, unit: str, target: str = "", ok: bool | None = None) -> Result:
        return Result("session", name + variant, value, unit, target, ok, detail)

    return [
        row(f"ticks ({DURATION_S:g} s at 1 kHz)", summary.ticks, "ticks"),
        row("missed deadlines", missed_pct, "%", "<= 0.1", missed_pct <= 0.1),
        row("lateness p50", late["p50"], "us"),
        row("lateness p99", late["p99"], "us", "<= 200", late["p99"] <= 200),
        row("lateness max", late["max"], "us"),
        row("compute per tick p50", compute["p50"], "us"),
        row("compute per tick p99", compute["p99"], "us"),
        row("sensor-to-command p50", s2c["p50"], "us"),
        row("sensor-to-command p99", s2c["p99"], "us", "<= 2000", s2c["p99"] <= 2000),
        row("recorder drops", result.drops, "rows", "== 0", result.drops == 0),
    ]


def _view(result: SessionResult) -> list[Result]:
    view = result.view
    assert view is not None
    detail = asdict(view)
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
