"""A 60 s emulated HIL session at 1 kHz with recording on: the loop's timing, measured.

The emulated rig runs in its own process, the recorder in another, the loop here, as
``hilrig record`` runs them. Reported: tick lateness p50/p99/max, missed deadlines (ticks whose
work ended after the next deadline) and sensor-to-command latency (F/T frame arrival -> the
Modbus write of the joint targets computed from it acknowledged), p50/p99.
"""

from __future__ import annotations

import tempfile
import threading
from pathlib import Path

from benchmarks.harness import Result
from hilrig.rig.session import SessionConfig, record_session

DURATION_S = 60.0


def run() -> list[Result]:
    out = Path(tempfile.mkdtemp(prefix="hilrig-bench-")) / "session.mcap"
    result = record_session(
        SessionConfig(out=out, subject_id="B001", scenario="hand-contact", duration_s=DURATION_S),
        stop=threading.Event(),
    )
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
    }
    return [
        Result("session", "ticks (60 s at 1 kHz)", summary.ticks, "ticks", "", None, detail),
        Result("session", "missed deadlines", missed_pct, "%", "<= 0.1", missed_pct <= 0.1, detail),
        Result("session", "lateness p50", late["p50"], "us", "", None, detail),
        Result("session", "lateness p99", late["p99"], "us", "<= 200", late["p99"] <= 200, detail),
        Result("session", "lateness max", late["max"], "us", "", None, detail),
        Result("session", "compute per tick p50", compute["p50"], "us", "", None, detail),
        Result("session", "compute per tick p99", compute["p99"], "us", "", None, detail),
        Result("session", "sensor-to-command p50", s2c["p50"], "us", "", None, detail),
        Result(
            "session",
            "sensor-to-command p99",
            s2c["p99"],
            "us",
            "<= 2000",
            s2c["p99"] <= 2000,
            detail,
        ),
        Result(
            "session", "recorder drops", result.drops, "rows", "== 0", result.drops == 0, detail
        ),
    ]
