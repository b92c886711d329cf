"""The machine's own timing floor: what no 1 kHz loop on it can beat, measured without hilrig.

After a wait for a quiet machine (:mod:`benchmarks.settle`, reported), the machine's settings
that cost deadlines (those ``hilrig doctor`` warns of, counted; every setting in the detail),
then calibration figures, read beside the session suite's (a loop
cannot be more punctual than the thread it runs on, nor than the link its samples come
through):

- **wake-up lateness**: a bare thread (no GC, 1 us timer slack, as the loop runs) sleeps to
  absolute deadlines 1 ms apart, idle and with a busy process burning one core; the share of
  wake-ups more than a period late bounds the session's missed deadlines from below;
- **fixed work after a wake-up**: right after each of those wake-ups the thread does the same
  small numpy work (16 products of a 6x6 matrix and a vector, about as long as a tick); its
  p99 against its p50 is the spread the machine alone puts on a tick's compute time;
- **CPU taken away**: a thread that never sleeps (normal priority: a SCHED_FIFO spinner would
  only measure Linux's real-time throttling, 50 ms a second) reads the clock in a tight loop;
  every gap over 100 us is time the OS or the hypervisor gave to someone else (steal on a VM);
- **link delivery**: a writer thread (as the emulated rig's, SCHED_FIFO 40 where granted) sends
  4 bytes every 1 ms through a pty (the emulated F/T sensor's link: a tty, whose bytes the
  kernel passes on in a worker thread of normal priority) and through a socket pair; a reader
  (as the loop) takes them in ``select``: the share delivered more than a period after writing.

Where the OS grants it (root or CAP_SYS_NICE), the waking thread runs SCHED_FIFO like the loop;
the detail says whether it did. The wake-ups and the links are measured by
:mod:`hilrig.machine.floor`, which ``hilrig doctor`` runs too.
"""

from __future__ import annotations

import gc
import socket
import subprocess
import sys
import time
from dataclasses import asdict

import numpy as np

from benchmarks.harness import Result, quantiles_us
from benchmarks.settle import settle
from hilrig.machine import read_settings
from hilrig.machine.floor import PERIOD_NS, Steal, WakeUps, delivery, pty_delivery, wake_ups

WAKE_S = 20.0
SPIN_S = 10.0
GAP_NS = 100_000
LINK_S = 10.0


def run() -> list[Result]:
    settled = settle("machine")
    steal = Steal()
    idle = wake_ups(WAKE_S)
    busy_core = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        busy = wake_ups(WAKE_S)
    finally:
        busy_core.kill()
        busy_core.wait()
    gaps = _spin_gaps()
    links = _delivery_rows("pty", pty_delivery(LINK_S))
    pair = socket.socketpair()
    links += _delivery_rows("socket pair", delivery(pair[0].detach(), pair[1].detach(), LINK_S))
    stolen = Result("machine", "hypervisor steal over the suite", steal.percent(), "% of CPU time")
    return [
        settled,
        _settings_row(),
        *_wake_rows(idle, ""),
        *_wake_rows(busy, " (a busy process on one core)"),
        *gaps,
        *links,
        stolen,
    ]


def _settings_row() -> Result:
    """How many of the machine's settings ``hilrig doctor`` warns of; all of them in the detail."""
    settings = read_settings()
    warned = [s.name for s in settings if s.verdict == "warn"]
    detail = {"warn": warned, "settings": [asdict(s) for s in settings]}
    name = "settings that cost deadlines (hilrig doctor's warnings)"
    return Result("machine", name, len(warned), "settings", detail=detail)


def _delivery_rows(link: str, delay_ns: np.ndarray) -> list[Result]:
    q = quantiles_us(delay_ns)
    over_pct = 100 * float(np.count_nonzero(delay_ns > PERIOD_NS)) / len(delay_ns)
    detail = {"messages": len(delay_ns), "delay_us": q, "over_a_period_pct": over_pct}
    name = f"1 kHz messages through a {link}"
    return [
        Result("machine", f"{name}: delay p99", q["p99"], "us", detail=detail),
        Result("machine", f"{name}: delivered over a period late", over_pct, "%", detail=detail),
    ]


def _wake_rows(measured: WakeUps, variant: str) -> list[Result]:
    late_ns, work_ns, fifo = measured.late_ns, measured.work_ns, measured.sched_fifo
    q = quantiles_us(late_ns)
    w = quantiles_us(work_ns)
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
        Result("machine", f"fixed work after a wake-up p50{variant}", w["p50"], "us", detail=w),
        Result("machine", f"fixed work after a wake-up p99{variant}", w["p99"], "us", detail=w),
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
