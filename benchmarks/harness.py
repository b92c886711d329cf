"""Shared pieces of the benchmarks: the result record and a quantile summary of timings (the
hypervisor's steal time is :class:`hilrig.machine.Steal`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
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
