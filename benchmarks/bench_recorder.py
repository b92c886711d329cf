"""The recorder at 1 kHz: what logging costs the tick, and what the recorder process costs.

This process plays the loop for ``DURATION_S``: every 1 ms it reserves, fills (every field, as
the loop does) and commits one wrist F/T, one joint-state and one tick row, and times that work
with ``perf_counter_ns``; a :class:`RecorderProcess` writes the 7 topics they become to MCAP.
Measured: the producer's cost per row kind and per tick (mean, p99), the recorder process's CPU
(utime + stime from /proc over the run) and the rows the rings refused (none expected).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.harness import Result, quantiles_us
from hilrig.recording import SessionInfo
from hilrig.rig import RecorderFeed, RecorderProcess

DURATION_S = 10.0
TICK_NS = 1_000_000
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
AXIS_ARRAYS = ("force", "offset", "offset_rate", "damping", "stiffness", "chi", "zeta")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run() -> list[Result]:
    with tempfile.TemporaryDirectory(prefix="hilrig-bench-") as tmp, RecorderFeed() as feed:
        info = SessionInfo.starting_now(
            session_id="bench-recorder", subject_id="B001", rig="benchmark", controller="adaptive"
        )
        recorder = RecorderProcess(Path(tmp) / "bench.mcap", feed=feed)
        recorder.start(info)
        try:
            return measure(feed, recorder)
        finally:
            recorder.stop()


def measure(feed: RecorderFeed, recorder: RecorderProcess) -> list[Result]:
    """Play the loop for DURATION_S at 1 kHz and return the results."""
    assert recorder.pid is not None
    rng = np.random.default_rng(0)
    wrench, q, axes = rng.normal(size=6), rng.normal(size=6), rng.normal(size=9)
    contact = np.zeros(9, np.int8)
    position, orientation = rng.normal(size=3), np.array([0.0, 0.0, 0.0, 1.0])
    ticks = round(DURATION_S * 1e9 / TICK_NS)
    costs_ns = np.zeros((ticks, 3), np.int64)  # F/T, joint, tick row
    cpu0 = cpu_s(recorder.pid)
    start = deadline = time.monotonic_ns()
    for i in range(ticks):
        deadline += TICK_NS
        time.sleep(max(0, deadline - time.monotonic_ns()) / 1e9)
        t_ns = time.monotonic_ns()
        t0 = time.perf_counter_ns()
        ft = feed.ft_slot()
        if ft is not None:
            ft["t_ns"], ft["seq"], ft["wrench"] = t_ns, i, wrench
        feed.commit_ft()
        t1 = time.perf_counter_ns()
        joint = feed.joint_slot()
        if joint is not None:
            joint["t_ns"], joint["device_t_ns"], joint["seq"] = t_ns, t_ns, i
            joint["q"], joint["qd"], joint["tau"] = q, q, q
        feed.commit_joint()
        t2 = time.perf_counter_ns()
        tick = feed.tick_slot()
        if tick is not None:
            tick["t_ns"], tick["tick"] = t_ns, i
            for name in AXIS_ARRAYS:
                tick[name] = axes
            tick["contact"] = contact
            tick["desired_position"], tick["desired_orientation"] = position, orientation
            tick["commanded_q"] = q
            tick["period_ns"], tick["compute_ns"], tick["lateness_ns"] = TICK_NS, 100_000, 0
            tick["overruns"], tick["queue_drops"] = 0, feed.drops
        feed.commit_tick()
        t3 = time.perf_counter_ns()
        costs_ns[i] = (t1 - t0, t2 - t1, t3 - t2)
    elapsed_s = (time.monotonic_ns() - start) / 1e9
    del ft, joint, tick  # the rings unmap only without live slot views
    while feed.ft.backlog or feed.joint.backlog or feed.tick.backlog:
        time.sleep(0.01)
    cpu = (cpu_s(recorder.pid) - cpu0) / elapsed_s * 100
    summary = recorder.stop()
    per_tick = quantiles_us(costs_ns.sum(axis=1))
    tick_row = quantiles_us(costs_ns[:, 2])
    detail = {
        "duration_s": elapsed_s,
        "ticks": ticks,
        "messages": summary.messages,
        "per_tick_us": per_tick,
        "tick_row_us": tick_row,
        "ft_row_us": quantiles_us(costs_ns[:, 0]),
        "joint_row_us": quantiles_us(costs_ns[:, 1]),
    }
    suite = "recorder"
    return [
        Result(
            suite,
            "tick row reserve+fill+commit, mean",
            tick_row["mean"],
            "us",
            "<= 5",
            tick_row["mean"] <= 5,
            detail,
        ),
        Result(suite, "tick row reserve+fill+commit, p99", tick_row["p99"], "us", "", None, detail),
        Result(suite, "producer per tick (3 rows), mean", per_tick["mean"], "us", "", None, detail),
        Result(suite, "producer per tick (3 rows), p99", per_tick["p99"], "us", "", None, detail),
        Result(
            suite, "CPU, recorder process at 1 kHz", cpu, "% of a core", "<= 25", cpu <= 25, detail
        ),
        Result(
            suite, "rows and events dropped", summary.drops, "", "0", summary.drops == 0, detail
        ),
        Result(
            suite,
            "messages written",
            summary.messages,
            "",
            f"{7 * ticks}",
            summary.messages == 7 * ticks,
            detail,
        ),
    ]
