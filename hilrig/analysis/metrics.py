"""Metrics of each collision event on each axis of its group, and tracking outside events.

Units follow the axis: Cartesian axes (x, y, z) in N, N*s, m, m/s; joints in N*m, N*m*s, rad,
rad/s; times in s. :func:`unit` names the unit of any metric on any group.

An event's window on an axis runs from its start to the next event of the same group (or the
end of the data): the offset keeps moving after the force is gone, so its largest value and its
return are looked for there. ``offset[n]`` belongs to the time of tick n + 1 (it is the offset
commanded at tick n: e[n] = e(t_n + dt), docs/analysis.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hilrig.analysis.events import (
    AxisGroup,
    CollisionEvent,
    FloatArray,
    edge_times,
    group_of,
    require_non_negative,
)
from hilrig.analysis.sources import Run
from hilrig.errors import AnalysisError

# metric -> (unit on Cartesian axes, unit on joints)
UNITS: dict[str, tuple[str, str]] = {
    "peak_force": ("N", "N*m"),
    "impulse": ("N*s", "N*m*s"),
    "max_offset": ("m", "rad"),
    "max_abs_offset": ("m", "rad"),
    "time_to_max_offset_s": ("s", "s"),
    "recovery_time_s": ("s", "s"),
    "peak_offset_rate": ("m/s", "rad/s"),
    "peak_commanded_joint_speed_rad_s": ("rad/s", "rad/s"),
    "tracking_rms": ("m", "rad"),
}


def unit(metric: str, group: AxisGroup | str) -> str:
    """The unit of ``metric`` on an axis of ``group``; AnalysisError for an unknown metric or
    group."""
    try:
        cartesian, joint = UNITS[metric]
    except KeyError as err:
        raise AnalysisError(f"unknown metric {metric!r}; known: {', '.join(UNITS)}") from err
    try:
        group = AxisGroup(group)
    except ValueError:
        known = ", ".join(g.value for g in AxisGroup)
        raise AnalysisError(f"unknown axis group {group!r}; known: {known}") from None
    return cartesian if group is AxisGroup.CARTESIAN else joint


@dataclass(frozen=True)
class MetricsConfig:
    """The recovery band: an offset has recovered once |offset| stays within
    max(``recovery_floor``, ``recovery_fraction`` * the event's max |offset|); the floor is in m
    on Cartesian axes and rad on joints (docs/analysis.md: 1 mm or 0.001 rad, 2 %)."""

    recovery_floor: float = 1e-3
    recovery_fraction: float = 0.02

    def __post_init__(self) -> None:
        require_non_negative(self)


DEFAULT_METRICS = MetricsConfig()


@dataclass(frozen=True)
class AxisMetrics:
    """One run's response to one event on one axis (units: see :data:`UNITS`).

    - ``peak_force``: the force (N or N*m) of largest magnitude during the event, signed.
    - ``impulse``: the integral of the force over the event, trapezoids on the samples from the
      last one at or below delta before the start to the first one after the end (so a pulse
      rising from and falling back to zero is integrated whole), N*s or N*m*s.
    - ``max_offset`` / ``max_abs_offset``: the offset (m or rad) of largest magnitude in the
      event's window, signed, and its magnitude.
    - ``time_to_max_offset_s``: from the event's start to that offset (the response time), s.
    - ``recovery_time_s``: from the force gone (``end_s``) until |offset| stays within the
      recovery band for good - through the rest of the window; None if it does not (the data
      ends or the next event starts first, or the data ends in contact), s.
    - ``peak_offset_rate``: the largest |offset rate| in the window, m/s or rad/s.
    - ``peak_commanded_joint_speed_rad_s``: the fastest commanded joint (any joint) in the
      window: the largest step of the commanded joint targets over the loop period; None where
      they were not recorded.
    """

    run: str
    event: int  # index into the events of the source
    group: AxisGroup
    axis: str
    start_s: float
    end_s: float
    peak_force: float
    impulse: float
    max_offset: float
    max_abs_offset: float
    time_to_max_offset_s: float
    recovery_time_s: float | None
    peak_offset_rate: float
    peak_commanded_joint_speed_rad_s: float | None


@dataclass(frozen=True)
class TrackingMetrics:
    """How far one run's axis strayed from the task outside its group's events.

    ``tracking_rms`` is the RMS of the offset (m or rad) over the ``samples`` ticks outside
    every event of the group (recovery included: the robot is off its task until it is back);
    None when no tick is outside.
    """

    run: str
    group: AxisGroup
    axis: str
    tracking_rms: float | None
    samples: int


def _next_starts(events: Sequence[CollisionEvent], end_s: float) -> list[float]:
    """For each event, when the next event of its group starts (``end_s`` if none does)."""
    following: dict[AxisGroup, float] = {}
    out = [end_s] * len(events)
    for n in range(len(events) - 1, -1, -1):
        out[n] = following.get(events[n].group, end_s)
        following[events[n].group] = events[n].start_s
    return out


def _commanded_speed(run: Run) -> tuple[FloatArray, FloatArray] | None:
    """(time of each step, fastest joint's |speed| over the step), s and rad/s.

    Each step is one loop tick, so it is divided by the loop period (the median interval), not
    by its own log-time interval: a late tick's catch-up, logged microseconds after it, moves
    the joints by one tick's worth and is no burst of speed.
    """
    t, q = run.commanded_t_s, run.commanded_joints_rad
    if t is None or q is None or t.shape[0] < 2:
        return None
    period_s = float(np.median(np.diff(t)))
    return t[1:], np.abs(np.diff(q, axis=0)).max(axis=1) / period_s


def _last_true(mask: np.ndarray) -> np.ndarray:
    """Per column of ``mask`` (R, k), the last row that is True, -1 where none is."""
    rows = mask.shape[0]
    last = rows - 1 - np.argmax(mask[::-1], axis=0)
    return np.where(mask.any(axis=0), last, -1)


def event_metrics(
    run: Run,
    events: Sequence[CollisionEvent],
    config: MetricsConfig = DEFAULT_METRICS,
) -> tuple[AxisMetrics, ...]:
    """The metrics of every event on every axis of its group present in ``run``.

    ``events`` are in start order, found on the force that ``run`` saw (possibly another run's
    copy of the same input); rows come in event then axis order.
    """
    t, edges = run.t_s, edge_times(run.t_s)
    last = t.shape[0]
    columns = {g: [i for i, a in enumerate(run.axes) if group_of(a) is g] for g in AxisGroup}
    commanded = _commanded_speed(run)
    found: list[AxisMetrics] = []
    for number, (event, next_s) in enumerate(
        zip(events, _next_starts(events, math.inf), strict=True)
    ):
        cols = columns[event.group]
        if not cols:
            continue
        i0 = int(np.searchsorted(t, event.start_s))
        i1 = int(np.searchsorted(edges, event.end_s))
        j = int(np.searchsorted(t, next_s))
        during = run.force[i0:i1, cols]
        peak = during[np.argmax(np.abs(during), axis=0), np.arange(len(cols))]
        lo, hi = max(i0 - 1, 0), min(i1, last - 1) + 1
        impulse = np.atleast_1d(np.trapezoid(run.force[lo:hi, cols], t[lo:hi], axis=0))
        window = run.offset[i0:j, cols]
        n_max = np.argmax(np.abs(window), axis=0)
        signed = window[n_max, np.arange(len(cols))]
        largest = np.abs(signed)
        recovery = _recovery(run.offset[max(i1 - 1, 0) : j, cols], largest, config)
        rate = np.abs(run.offset_rate[i0:j, cols]).max(axis=0)
        speed = _peak_speed(commanded, event.start_s, min(next_s, float(edges[-1])))
        for k, col in enumerate(cols):
            recovered = recovery[k] if i1 < last else -1
            found.append(
                AxisMetrics(
                    run=run.name,
                    event=number,
                    group=event.group,
                    axis=run.axes[col],
                    start_s=event.start_s,
                    end_s=event.end_s,
                    peak_force=float(peak[k]),
                    impulse=float(impulse[k]),
                    max_offset=float(signed[k]),
                    max_abs_offset=float(largest[k]),
                    time_to_max_offset_s=float(edges[i0 + n_max[k] + 1] - event.start_s),
                    recovery_time_s=(
                        None if recovered < 0 else float(edges[i1 + recovered] - event.end_s)
                    ),
                    peak_offset_rate=float(rate[k]),
                    peak_commanded_joint_speed_rad_s=speed,
                )
            )
    return tuple(found)


def _recovery(after: FloatArray, largest: FloatArray, config: MetricsConfig) -> np.ndarray:
    """Per column, how many rows of ``after`` (from the row whose offset belongs to the force's
    end) pass before |offset| is inside the band for good; -1 if it never is."""
    band = np.maximum(config.recovery_floor, config.recovery_fraction * largest)
    last_out = _last_true(np.abs(after) > band)
    settled = last_out + 1
    return np.where(settled < after.shape[0], settled, -1)


def _peak_speed(
    commanded: tuple[FloatArray, FloatArray] | None, start_s: float, stop_s: float
) -> float | None:
    if commanded is None:
        return None
    times, speed = commanded
    a, b = np.searchsorted(times, [start_s, stop_s])
    return float(speed[a:b].max()) if b > a else None


def tracking_metrics(run: Run, events: Sequence[CollisionEvent]) -> tuple[TrackingMetrics, ...]:
    """The tracking RMS of every axis of ``run`` outside its group's events."""
    edges = edge_times(run.t_s)
    last = run.t_s.shape[0]
    outside: dict[AxisGroup, np.ndarray] = {}
    for group in AxisGroup:
        spans = [e for e in events if e.group is group]
        depth = np.zeros(last + 1, dtype=np.int64)
        np.add.at(depth, np.searchsorted(run.t_s, [e.start_s for e in spans]), 1)
        np.add.at(depth, np.searchsorted(edges, [e.end_s for e in spans]), -1)
        outside[group] = np.cumsum(depth[:last]) == 0
    # masked sums of squares as one three-operand product per group (a pass over the offsets,
    # no squares stored, no rows gathered: 4 ms against 11 ms for 10 minutes of 9 axes; einsum,
    # not BLAS, so that no thread pool is woken); a column that is not finite somewhere
    # (0 x inf is NaN) is summed over its rows alone, as it is
    offset = run.offset
    groups = {group_of(axis) for axis in run.axes}
    samples = {group: int(np.count_nonzero(outside[group])) for group in groups}
    with np.errstate(invalid="ignore", over="ignore"):
        sums = {
            g: np.einsum("i,ij,ij->j", outside[g].astype(np.float64), offset, offset)
            for g in groups
            if samples[g]
        }
    found = []
    for col, axis in enumerate(run.axes):
        group = group_of(axis)
        rms = None
        if group in sums:
            total = float(sums[group][col])
            if not math.isfinite(total):
                kept = offset[outside[group], col]
                with np.errstate(over="ignore"):
                    total = float(np.sum(kept * kept))
            rms = math.sqrt(total / samples[group])
        found.append(TrackingMetrics(run.name, group, axis, rms, samples[group]))
    return tuple(found)
