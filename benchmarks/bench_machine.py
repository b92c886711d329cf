"""The machine's own timing floor: what no 1 kHz loop on it can beat, measured without hilrig.

Two calibration figures, read beside the session suite's (a loop cannot be more punctual than
the thread it runs on):

- **wake-up lateness**: a bare thread (no GC, 1 us timer slack, as the loop runs) sleeps to
  absolute deadlines 1 ms apart, idle and with a busy process burning one core; the share of
  wake-ups more than a period late bounds the session's missed deadlines from below;
- **CPU taken away**: a thread that never sleeps (normal priority: a SCHED_FIFO spinner would
  only measure Linux's real-time throttling, 50 ms a second) reads the clock in a tight loop;
  every gap over 100 us is time the OS or the hypervisor gave to someone else (steal on a VM).

Where the OS grants it (root or CAP_SYS_NICE), the waking thread runs SCHED_FIFO like the loop;
the detail says whether it did.
"""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import time

import numpy as np

from benchmarks.harness import Result, quantiles_us
from hilrig.timing import realtime_python

PERIOD_NS = 1_000_000
WAKE_S = 20.0
SPIN_S = 10.0
GAP_NS = 100_000


def run() -> list[Result]:
    idle = _wake_ups()
    busy_core = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        busy = _wake_ups()
    finally:
        busy_core.kill()
        busy_core.wait()
    gaps = _spin_gaps()
    return _wake_rows(idle, "") + _wake_rows(busy, " (a busy process on one core)") + gaps


def _wake_ups() -> tuple[np.ndarray, bool]:
    """Lateness (ns) of each wake-up of a thread sleeping to deadlines one period apart, and
    whether the thread ran SCHED_FIFO."""
    count = round(WAKE_S * 1e9 / PERIOD_NS)
    late = np.zeros(count, dtype=np.int64)
    with realtime_python():
        fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
        deadline = time.monotonic_ns() + PERIOD_NS
        for i in range(count):
            remaining = deadline - time.monotonic_ns()
            if remaining > 0:
                time.sleep(remaining / 1e9)
            late[i] = time.monotonic_ns() - deadline
            deadline += PERIOD_NS
    return late, fifo


def _wake_rows(measured: tuple[np.ndarray, bool], variant: str) -> list[Result]:
    late_ns, fifo = measured
    q = quantiles_us(late_ns)
    over_pct = 100 * float(np.count_nonzero(late_ns > PERIOD_NS)) / len(late_ns)
    detail = {
        "wake_ups": len(late_ns),
        "lateness_us": q,
        "over_a_period_pct": over_pct,
        "sched_fifo": fifo,
    }
    name = "bare thread's 1 kHz wake-up"
    return [
        Result("machine", f"{name} lateness p99{variant}", q["p99"], "us", detail=detail),
        Result("machine", f"{name} lateness max{variant}", q["max"], "us", detail=detail),
        Result("machine", f"{name}s over a period late{variant}", over_pct, "%", detail=detail),
    ]


def _spin_gaps() -> list[Result]:
    """Gaps over GAP_NS between two clock reads of a thread that never sleeps."""
    gaps: list[int] = []
    gc.disable()
    try:
        start = previous = time.monotonic_ns()
        end = start + round(SPIN_S * 1e9)
        while previous < end:
            now = time.monotonic_ns()
            if now - previous > GAP_NS:
                gaps.append(now - previous)
            previous = now
    finally:
        gc.enable()
    lost = np.asarray(gaps, dtype=np.int64)
    detail = {
        "seconds": SPIN_S,
        "gaps_over_100us": len(gaps),
        "gaps_over_1ms": int(np.count_nonzero(lost > PERIOD_NS)),
        "max_gap_us": float(lost.max() / 1e3) if len(gaps) else 0.0,
    }
    return [
        Result(
            "machine",
            f"CPU taken from a spinning thread: gaps > 1 ms per {SPIN_S:g} s",
            detail["gaps_over_1ms"],
            "gaps",
            detail=detail,
        ),
        Result(
            "machine",
            "CPU taken from a spinning thread: time lost in gaps > 100 us",
            100 * float(lost.sum()) / (SPIN_S * 1e9),
            "%",
            detail=detail,
        ),
        Result(
            "machine", "CPU taken from a spinning thread: longest gap", detail["max_gap_us"], "us"
        ),
    ]
