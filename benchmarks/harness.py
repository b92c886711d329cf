"""Shared pieces of the benchmarks: the result record, a quantile summary of timings and the
hypervisor's steal time."""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Result:
    """One measured number; ``target`` is the issue's bound in the same unit, when it has one."""

    suite: str
    name: str
    value: float
    unit: str
    target: str = ""
    passed: bool | None = None
    detail: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def quantiles_us(samples_ns: ArrayLike) -> dict[str, float]:
    """Mean, p50, p99, p99.9 and max of nanosecond samples, in microseconds."""
    us = np.asarray(samples_ns, dtype=np.float64) / 1e3
    return {
        "mean": float(us.mean()),
        "p50": float(np.percentile(us, 50)),
        "p99": float(np.percentile(us, 99)),
        "p99.9": float(np.percentile(us, 99.9)),
        "max": float(us.max()),
    }


CLOCK_TICKS_S = os.sysconf("SC_CLK_TCK")


class Steal:
    """The share of the machine's CPU time the hypervisor gave to others (``steal`` in
    /proc/stat) between construction and ``percent()``: time no thread here could run, however
    high its priority. Summed over all CPUs, in % of (wall time x CPUs); NaN where /proc/stat
    has no steal column."""

    def __init__(self) -> None:
        self._t0_s, self._steal0_s = time.monotonic(), _steal_s()

    def percent(self) -> float:
        elapsed_s = time.monotonic() - self._t0_s
        cpus = os.cpu_count() or 1
        return 100 * (_steal_s() - self._steal0_s) / (elapsed_s * cpus)


def _steal_s() -> float:
    """Steal time of all CPUs so far, s (NaN if not reported)."""
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
    return int(fields[8]) / CLOCK_TICKS_S if len(fields) > 8 else float("nan")
