"""Collision events from force channels: a threshold, a merge of close events, a debounce.

Each axis group has one contact magnitude per sample: the Euclidean norm of its Cartesian forces
(x, y, z; N) or the largest absolute joint torque (joint1..joint6; N*m). A collision event is a
stretch of samples whose magnitude exceeds ``delta``; stretches separated by less than
``merge_gap_s`` are merged into one event (contact chattering about the threshold), then events
whose time above delta totals less than ``debounce_s`` are dropped (sensor noise crossing the
threshold for a sample or two, however many such spikes fall close together). Everything is
vectorised: an hour of 1 kHz data takes a fraction of a second.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from enum import StrEnum
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import AnalysisError

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

CARTESIAN_AXES = ("x", "y", "z")
JOINT_AXES = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")

FloatArray = NDArray[np.float64]


class AxisGroup(StrEnum):
    """The two axis groups a controller runs: the end effector's Cartesian axes and the joints."""

    CARTESIAN = "cartesian"  # x, y, z: forces in N, offsets in m
    JOINT = "joint"  # joint1..joint6: torques in N*m, offsets in rad

    @property
    def axes(self) -> tuple[str, ...]:
        """The group's axes, in controller order."""
        return CARTESIAN_AXES if self is AxisGroup.CARTESIAN else JOINT_AXES


def group_of(axis: str) -> AxisGroup:
    """The group of ``axis`` (``x``..``z`` or ``joint1``..``joint6``); AnalysisError otherwise."""
    for group in AxisGroup:
        if axis in group.axes:
            return group
    raise AnalysisError(f"unknown axis {axis!r}; known: {', '.join(CARTESIAN_AXES + JOINT_AXES)}")


@dataclass(frozen=True)
class EventConfig:
    """How events are found: ``delta`` in N (Cartesian) or N*m (joints), times in s.

    The defaults are the paper's collision threshold (0.2 N and 0.2 N*m) with a 20 ms debounce
    (least time above delta) and a 50 ms merge gap. Raises AnalysisError for negative or
    non-finite values.
    """

    delta: float = 0.2
    debounce_s: float = 0.02
    merge_gap_s: float = 0.05

    def __post_init__(self) -> None:
        require_non_negative(self, "event ")


def require_non_negative(settings: DataclassInstance, prefix: str = "") -> None:
    """AnalysisError naming the first field of ``settings`` that is negative or not finite."""
    for name in (f.name for f in fields(settings)):
        value = getattr(settings, name)
        if not math.isfinite(value) or value < 0:
            raise AnalysisError(f"{prefix}{name} must be finite and >= 0, got {value}")


DEFAULT_EVENTS = EventConfig()


@dataclass(frozen=True)
class CollisionEvent:
    """One collision of one axis group.

    ``start_s`` is the time of the first sample above delta, ``end_s`` the time of the first
    sample back at or below it ("force gone"; one sample interval past the last sample when the
    data ends in contact); ``peak`` is the largest contact magnitude in the event, N (Cartesian
    norm) or N*m (largest |torque|). Times are s on the input's time axis.
    """

    group: AxisGroup
    start_s: float
    end_s: float
    peak: float

    @property
    def duration_s(self) -> float:
        """end_s - start_s, s."""
        return self.end_s - self.start_s


def edge_times(t_s: FloatArray) -> FloatArray:
    """``t_s`` with one more time appended, one sample interval past the last (s).

    Index i of the result is when sample i starts; index T is when the data ends. Sample i's
    offset, commanded at tick i, belongs to index i + 1 (docs/analysis.md: e[n] = e(t_n + dt)).
    """
    last_interval = float(t_s[-1] - t_s[-2]) if t_s.shape[0] > 1 else 0.0
    return np.append(t_s, t_s[-1] + last_interval)


def magnitude(force: FloatArray, group: AxisGroup) -> FloatArray:
    """Per-sample contact magnitude of ``force`` (T, k): the norm (Cartesian) or max |tau|."""
    if group is AxisGroup.CARTESIAN:
        return np.asarray(np.sqrt(np.einsum("ij,ij->i", force, force)), dtype=np.float64)
    return np.asarray(np.max(np.abs(force), axis=1), dtype=np.float64)


def detect_group(
    t_s: FloatArray,
    contact_magnitude: FloatArray,
    group: AxisGroup,
    config: EventConfig = DEFAULT_EVENTS,
) -> tuple[CollisionEvent, ...]:
    """The events of one group from its magnitude (T,) sampled at increasing ``t_s`` (s)."""
    above = contact_magnitude > config.delta
    if not above.any():
        return ()
    step = np.diff(above.astype(np.int8), prepend=np.int8(0), append=np.int8(0))
    starts = np.flatnonzero(step == 1)  # first sample above
    stops = np.flatnonzero(step == -1)  # first sample back below (T when the data ends in contact)
    edges = edge_times(t_s)
    above_s = edges[stops] - edges[starts]
    first = np.concatenate(([True], edges[starts[1:]] - edges[stops[:-1]] >= config.merge_gap_s))
    heads = np.flatnonzero(first)  # the first run of each merged event
    starts = starts[heads]
    stops = stops[np.append(heads[1:] - 1, stops.shape[0] - 1)]
    # debounced on the time spent above delta, so sparse noise spikes never merge into an event
    long_enough = np.add.reduceat(above_s, heads) >= config.debounce_s
    starts, stops = starts[long_enough], stops[long_enough]
    if starts.size == 0:
        return ()
    padded = np.append(contact_magnitude, 0.0)  # a stop may be T
    peaks = np.maximum.reduceat(padded, np.column_stack((starts, stops)).ravel())[::2]
    return tuple(
        CollisionEvent(group, float(edges[a]), float(edges[b]), float(p))
        for a, b, p in zip(starts, stops, peaks, strict=True)
    )


def detect(
    t_s: FloatArray,
    force: FloatArray,
    axes: tuple[str, ...],
    config: EventConfig = DEFAULT_EVENTS,
) -> tuple[CollisionEvent, ...]:
    """The events of every group present in ``axes``, ordered by start time.

    ``force`` (T, A) holds one column per name in ``axes`` (N or N*m); ``t_s`` (T,) is
    increasing, s. A group counts only the axes present. Raises AnalysisError for an unknown
    axis or mismatched shapes.
    """
    if force.ndim != 2 or force.shape != (t_s.shape[0], len(axes)):
        raise AnalysisError(f"force {force.shape} does not match {t_s.shape[0]} times x {axes}")
    found: list[CollisionEvent] = []
    groups = [group_of(axis) for axis in axes]
    for group in AxisGroup:
        columns = [i for i, g in enumerate(groups) if g is group]
        if columns and t_s.shape[0]:
            found += detect_group(t_s, magnitude(force[:, columns], group), group, config)
    return tuple(sorted(found, key=lambda e: (e.start_s, e.group.value)))
