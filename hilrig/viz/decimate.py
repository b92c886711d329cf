"""Decimation for display: which samples a plot or a 3D view shows of a long session.

The recording and the replay results are never touched; only what is sent to the viewer is
thinned. Time series keep, per bucket of consecutive samples, the sample at the bucket's minimum
and the one at its maximum (in time order), so that every peak and every step a reader looks
for survives; 3D views keep, per bucket, the sample where the force is largest, so that the
robot and the force arrow are shown at the moment of a collision's peak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.errors import ViewError

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Decimation:
    """How much a display thinned a series: ``samples`` in, at most ``points`` out."""

    samples: int
    points: int

    @classmethod
    def of(cls, samples: int, max_points: int) -> Decimation:
        """The thinning of ``samples`` under a budget of ``max_points`` (0: none)."""
        return cls(samples, samples if max_points == 0 else min(samples, max_points))

    @property
    def active(self) -> bool:
        return self.points < self.samples

    @property
    def factor(self) -> float:
        """Samples per displayed point (1.0 when nothing is thinned)."""
        return self.samples / self.points if self.points else 1.0


def minmax_indices(values: FloatArray, max_points: int) -> IntArray:
    """Indices of the samples of ``values`` (N,) a plot of at most ``max_points`` shows.

    All N when N <= ``max_points`` (or ``max_points`` is 0: no decimation); otherwise
    ``max_points // 2`` buckets of consecutive samples each give the index of their minimum and
    of their maximum, ascending (one index when both are the same sample). NaN samples are
    never chosen unless a bucket holds nothing else.
    """
    n = len(values)
    if _keeps_all(n, max_points):
        return np.arange(n, dtype=np.int64)
    buckets = max(1, max_points // 2)
    return _minmax(np.ascontiguousarray(values, dtype=np.float64), buckets)


def peak_indices(magnitude: FloatArray, max_points: int) -> IntArray:
    """Indices of at most ``max_points`` samples, one per bucket of consecutive samples: the one
    of largest ``magnitude`` (the first on ties or all-NaN). All when N <= ``max_points`` or
    ``max_points`` is 0."""
    n = len(magnitude)
    if _keeps_all(n, max_points):
        return np.arange(n, dtype=np.int64)
    return _peaks(np.ascontiguousarray(magnitude, dtype=np.float64), max_points)


def _keeps_all(samples: int, max_points: int) -> bool:
    """Whether a budget of ``max_points`` (0: none) keeps all ``samples``; ViewError if < 0."""
    if max_points < 0:
        raise ViewError(f"max_points {max_points} must be >= 0")
    return max_points == 0 or samples <= max_points


@njit(cache=True, nogil=True)
def _bounds(n: int, buckets: int, b: int) -> tuple[int, int]:
    return (b * n) // buckets, ((b + 1) * n) // buckets


@njit(cache=True, nogil=True)
def _minmax(values: FloatArray, buckets: int) -> IntArray:  # pragma: no cover - compiled
    n = values.shape[0]
    out = np.empty(2 * buckets, dtype=np.int64)
    count = 0
    for b in range(buckets):
        lo, hi = _bounds(n, buckets, b)
        i_min = -1
        i_max = -1
        for i in range(lo, hi):
            v = values[i]
            if v != v:  # NaN
                continue
            if i_min < 0 or v < values[i_min]:
                i_min = i
            if i_max < 0 or v > values[i_max]:
                i_max = i
        if i_min < 0:
            out[count] = lo
            count += 1
        elif i_min == i_max:
            out[count] = i_min
            count += 1
        else:
            out[count] = min(i_min, i_max)
            out[count + 1] = max(i_min, i_max)
            count += 2
    return out[:count].copy()


@njit(cache=True, nogil=True)
def _peaks(magnitude: FloatArray, buckets: int) -> IntArray:  # pragma: no cover - compiled
    n = magnitude.shape[0]
    out = np.empty(buckets, dtype=np.int64)
    for b in range(buckets):
        lo, hi = _bounds(n, buckets, b)
        best = lo
        for i in range(lo, hi):
            v = magnitude[i]
            if v == v and (magnitude[best] != magnitude[best] or v > magnitude[best]):
                best = i
        out[b] = best
    return out
