"""The typed samples a session records, one type per message schema (see :mod:`.schema`).

Every sample carries ``t_ns``: the host monotonic clock (``time.monotonic_ns``) when the sample
was received or produced. Device samples also keep the device's own time and sequence number
when the device gives them (``device_t_ns``, ``device_seq``); the writer stores them as the MCAP
publish time and sequence. Units are SI: N, N*m, m, rad, s.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

Vec3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]  # x, y, z, w


@dataclass(frozen=True, slots=True)
class WrenchSample:
    """A force/torque sample: ``force`` (N) and ``torque`` (N*m) in the channel's frame."""

    t_ns: int
    force: Vec3
    torque: Vec3
    device_t_ns: int | None = None
    device_seq: int | None = None


@dataclass(frozen=True, slots=True)
class JointSample:
    """Joint positions (rad), velocities (rad/s) and efforts (joint torque, N*m), in the order of
    the channel's joint names; arrays a channel does not record are left empty."""

    t_ns: int
    position: Sequence[float]
    velocity: Sequence[float] = ()
    effort: Sequence[float] = ()
    device_t_ns: int | None = None
    device_seq: int | None = None


@dataclass(frozen=True, slots=True)
class PoseSample:
    """An end-effector pose: ``position`` (m) and unit quaternion ``orientation`` (x, y, z, w)."""

    t_ns: int
    position: Vec3
    orientation: Quaternion


class ContactState(enum.IntEnum):
    """Algorithm 2 contact state of an axis group: the ``contact_state`` codes on disk, and
    those of the controller (:mod:`hilrig.control` re-exports this enum; its kernel emits them)."""

    FREE = 0
    CONTACT = 1
    HOLDING = 2
    RECOVERING = 3


@dataclass(frozen=True, slots=True)
class ControllerSample:
    """One tick of an admittance controller, one entry per axis of the channel (in its order).

    ``force`` f_i (N or N*m), ``offset`` e_i (m or rad), ``offset_rate`` e'_i (m/s or rad/s),
    ``damping`` b_i, ``stiffness`` k_i, ``chi`` and ``zeta`` (dimensionless), ``contact_state``
    :class:`ContactState` codes.
    """

    t_ns: int
    force: Sequence[float]
    offset: Sequence[float]
    offset_rate: Sequence[float]
    damping: Sequence[float]
    stiffness: Sequence[float]
    chi: Sequence[float]
    zeta: Sequence[float]
    contact_state: Sequence[int]


class EventKind(enum.IntEnum):
    """The ``kind`` codes of ``hilrig_msgs/msg/Event``."""

    COLLISION_START = 1
    COLLISION_END = 2
    RECOVERED = 3
    FAULT = 4
    OPERATOR_MARK = 5


@dataclass(frozen=True, slots=True)
class EventRecord:
    """A discrete event: what happened, who raised it, one line of detail, the axis group or
    device it concerns and a qualifying number (e.g. peak force in N; NaN when none)."""

    t_ns: int
    kind: EventKind
    source: str
    detail: str = ""
    axis: str = ""
    value: float = math.nan


@dataclass(frozen=True, slots=True)
class LoopTiming:
    """Timing of one loop tick (ns); ``overruns`` and ``queue_drops`` count since the start."""

    t_ns: int
    tick: int
    period_ns: int
    compute_ns: int
    lateness_ns: int
    overruns: int
    queue_drops: int


@dataclass(frozen=True, slots=True)
class TextSample:
    """A text message (std_msgs/msg/String), e.g. the URDF on ``/robot_description``."""

    t_ns: int
    text: str


Sample = (
    WrenchSample
    | JointSample
    | PoseSample
    | ControllerSample
    | EventRecord
    | LoopTiming
    | TextSample
)
