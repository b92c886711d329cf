"""Sweeps: throughput of ``hilrig sweep`` with 1 and 2 local workers, and Ray against the local
pool on the same sweep, tasks per second.

The sweep: 8 force tables of 10 minutes at 1 kHz (9 axes, a collision every 30 s, as
:func:`benchmarks.bench_control.session_trace`) x 9 adaptive parameter sets (``a1`` 5 to 20) =
72 tasks of 0.25-0.35 s each on a fast machine (replay, events, metrics, one Parquet
partition). Each run writes into a fresh folder (a rerun would skip everything); each engine
runs twice, alternating, and its best time counts (the machine's other load is in the details).
Until 2026-12-05 the sweep had 3 parameter sets (24 tasks): each new worker's first task, which
takes its memory fresh, then weighed on two workers' 12 tasks each as much as the throughput
itself (docs/sweeps.md). Ray runs on a local instance of 2 CPUs, started before the timing (its
start-up, several seconds, is reported apart): what is compared is the engines' cost per task,
including each Ray worker's first import of hilrig. Beside them, the control suite's reference:
``scipy.signal.lfilter`` over the same trace's 9 axes, in this process, and the machine's own
scaling from one process to two, without hilrig: the same compute-bound loop (``np.sin`` over
32 KiB, in cache) and the same memory-bound one (copying 256 MiB), each timed alone and then in
two processes at once: what two workers can gain here.
"""

from __future__ import annotations

import multiprocessing
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks.bench_control import DT_S, lfilter_axes, nine_axes, session_trace
from benchmarks.harness import Result
from hilrig.replay import parse_specs
from hilrig.sweep import find_inputs, plan, sweep

SUITE = "sweep"
SOURCES = 8
TRACE_S = 600
SPEEDUP_TARGET = 1.7
RAY_RATIO_TARGET = 1.2
REPEATS = 2
PARAMETER_SETS = "adaptive.a1=5:20:9"


def write_traces(folder: Path) -> list[Path]:
    """The sweep's inputs: force tables (t, fx fy fz, tau1..tau6)."""
    names = ["fx", "fy", "fz", *(f"tau{j}" for j in range(1, 7))]
    paths = []
    for n in range(SOURCES):
        force = session_trace(TRACE_S, seed=n)
        columns = {"t": np.arange(force.shape[0]) * DT_S} | dict(zip(names, force.T, strict=True))
        path = folder / f"trace-{n}.parquet"
        pd.DataFrame(columns).to_parquet(path)
        paths.append(path)
    return paths


def lfilter_rate() -> float:
    """M axis-steps/s of lfilter over one trace's 9 axes (median of 3), as bench_control."""
    force = session_trace(TRACE_S)
    columns = np.ascontiguousarray(force.T)
    params = nine_axes("adaptive", "adaptive-joint")
    times = []
    for _ in range(4):
        start = time.perf_counter()
        lfilter_axes(params, columns)
        times.append(time.perf_counter() - start)
    return force.size / float(np.median(times[1:])) / 1e6


def _loop_s(kind: str, start: Any, results: Any) -> None:
    """Put the seconds of one fixed loop in ``results``: ``compute`` (sin over 32 KiB, in
    cache) or ``memory`` (copy 256 MiB x 8); ``start``, a Barrier, lines up the processes."""
    if kind == "compute":
        x = np.linspace(0.0, 1.0, 4096)
        y, repeats = np.empty_like(x), 40_000
    else:
        x = np.ones(2**25)
        y, repeats = np.zeros_like(x), 8
    step = (lambda: np.sin(x, out=y)) if kind == "compute" else (lambda: np.copyto(y, x))
    step()  # pages touched, code warm
    start.wait()
    began = time.perf_counter()
    for _ in range(repeats):
        step()
    results.put(time.perf_counter() - began)


def machine_scaling() -> dict[str, float]:
    """Per kind of loop, the speed-up of two processes over one (2 x alone / together, the
    slower of the two): 2.0 is perfect scaling."""
    context = multiprocessing.get_context("fork")
    found = {}
    for kind in ("compute", "memory"):
        seconds = []
        for count in (1, 2):
            start, results = context.Barrier(count), context.Queue()
            processes = [
                context.Process(target=_loop_s, args=(kind, start, results)) for _ in range(count)
            ]
            for process in processes:
                process.start()
            seconds.append(max(results.get() for _ in processes))
            for process in processes:
                process.join()
        found[kind] = 2.0 * seconds[0] / seconds[1]
    return found


def _children_cpu_s() -> float:
    """CPU seconds of this process's ended children (a pool's workers, once it has shut down)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run() -> list[Result]:
    import ray

    work = Path(tempfile.mkdtemp(prefix="hilrig-bench-sweep-"))
    try:
        inputs = find_inputs(write_traces(work))
        specs = parse_specs(["adaptive"], sweeps=[PARAMETER_SETS])
        tasks = plan(inputs, specs, closed_loop=False)
        sweep(tasks[:2], work / "warm", workers=1)  # kernels compiled and cached, files in cache
        load = os.getloadavg()[0]
        runs: dict[str, list[float]] = {"local-1": [], "local-2": [], "ray-2": []}
        cpu: dict[str, list[float]] = {"local-1": [], "local-2": []}  # CPU s per task
        for repeat in range(REPEATS):  # alternating; the best of each (others share the cores)
            for name, workers in (("local-1", 1), ("local-2", 2)):
                before = _children_cpu_s()
                runs[name].append(sweep(tasks, work / f"{name}-{repeat}", workers=workers).seconds)
                cpu[name].append((_children_cpu_s() - before) / len(tasks))
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        start = time.perf_counter()
        ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING", log_to_driver=False)
        ray_start_s = time.perf_counter() - start
        try:
            for repeat in range(REPEATS):
                runs["ray-2"].append(sweep(tasks, work / f"ray-{repeat}", engine="ray").seconds)
        finally:
            ray.shutdown()
        reference = lfilter_rate()
        machine = machine_scaling()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    seconds = {name: min(times) for name, times in runs.items()}
    rate = {name: len(tasks) / s for name, s in seconds.items()}
    speedup = seconds["local-1"] / seconds["local-2"]
    ratio = seconds["ray-2"] / seconds["local-2"]
    detail = {
        "tasks": len(tasks),
        "sources": SOURCES,
        "trace_s": TRACE_S,
        "seconds": runs,
        "load_average_1min_at_start": load,
        "worker_cpu_s_per_task": cpu,
        "ray_start_s": ray_start_s,
        "cores": len(os.sched_getaffinity(0)),
        "machine_speedup_2_processes": machine,
    }
    return [
        Result(SUITE, "local, 1 worker", rate["local-1"], "tasks/s", "", None, detail),
        Result(SUITE, "local, 2 workers", rate["local-2"], "tasks/s", "", None, detail),
        Result(
            SUITE,
            "speed-up 2 workers / 1",
            speedup,
            "x",
            f">= {SPEEDUP_TARGET}",
            speedup >= SPEEDUP_TARGET,
            detail,
        ),
        Result(SUITE, "ray, 2 CPUs (local instance)", rate["ray-2"], "tasks/s", "", None, detail),
        Result(
            SUITE,
            "ray time / local pool time (2 each)",
            ratio,
            "x",
            f"<= {RAY_RATIO_TARGET}",
            ratio <= RAY_RATIO_TARGET,
            detail,
        ),
        Result(SUITE, "ray start-up (not in the above)", ray_start_s, "s", "", None, detail),
        Result(SUITE, "lfilter fixed (reference)", reference, "M axis-steps/s", "", None, detail),
        Result(
            SUITE,
            "machine: 2 processes / 1, compute-bound loop (reference)",
            machine["compute"],
            "x",
            "",
            None,
            detail,
        ),
        Result(
            SUITE,
            "machine: 2 processes / 1, memory copy (reference)",
            machine["memory"],
            "x",
            "",
            None,
            detail,
        ),
    ]
