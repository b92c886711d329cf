"""Rows to samples: the recorder turns the loop's rows (dtypes of :mod:`.records`) into the
recording's typed samples, each with its topic."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import fields

from hilrig.recording import (
    ControllerSample,
    EventKind,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    WrenchSample,
)
from hilrig.recording.schema import TICK_FIELDS
from hilrig.rig.rings import Rows

FT_TOPIC = "/ft/wrist"
JOINT_TOPIC = "/joint_states"
INPUT_TOPIC = "/controller/input"
STATE_TOPIC = "/controller/state"
DESIRED_TOPIC = "/trajectory/desired"
COMMANDED_TOPIC = "/trajectory/commanded"
LOOP_TOPIC = "/diagnostics/loop"
SERVO_TOPIC = "/robot/servo"
EVENTS_TOPIC = "/events"

Messages = Iterator[tuple[str, Sample]]


def ft_samples(rows: Rows) -> Messages:
    """``/ft/wrist`` samples of FT_DTYPE rows (sensor frame, N and N*m). The driver's frame
    counter goes to ``device_seq``, which the writer keeps only on device-clock channels."""
    for t_ns, seq, w in zip(
        rows["t_ns"].tolist(), rows["seq"].tolist(), rows["wrench"].tolist(), strict=True
    ):
        yield FT_TOPIC, WrenchSample(t_ns, (w[0], w[1], w[2]), (w[3], w[4], w[5]), device_seq=seq)


def joint_samples(rows: Rows) -> Messages:
    """``/joint_states`` samples of JOINT_DTYPE rows, stamped with the robot's time and sequence."""
    columns = ("t_ns", "q", "qd", "tau", "device_t_ns", "seq")
    for t_ns, q, qd, tau, device_t_ns, seq in zip(
        *(rows[c].tolist() for c in columns), strict=True
    ):
        yield JOINT_TOPIC, JointSample(t_ns, q, qd, tau, device_t_ns=device_t_ns, device_seq=seq)


def servo_samples(rows: Rows) -> Messages:
    """``/robot/servo`` samples of SERVO_DTYPE rows: each servo call's targets (rad), stamped
    when it left."""
    for t_ns, q in zip(rows["t_ns"].tolist(), rows["q"].tolist(), strict=True):
        yield SERVO_TOPIC, JointSample(t_ns, q)


_STATE_COLUMNS = tuple((f.name, f.state) for f in TICK_FIELDS if f.state)
_TIMING_COLUMNS = tuple(f.name for f in fields(LoopTiming) if f.name != "t_ns")


def tick_samples(rows: Rows) -> Messages:
    """Per TICK_DTYPE row, in this order: ``/controller/input`` (the compensated wrist wrench
    in the base frame, N and N*m), ``/controller/state`` (all axes), ``/trajectory/desired``,
    ``/trajectory/commanded`` (positions only) and ``/diagnostics/loop``. Fields are read by
    name: the state's from :data:`~hilrig.recording.schema.TICK_FIELDS`, the timing's as
    :class:`~hilrig.recording.LoopTiming` names them."""
    column = {name: rows[name].tolist() for name in rows.dtype.names or ()}
    state = [(array, column[name]) for name, array in _STATE_COLUMNS]
    timing = [(name, column[name]) for name in _TIMING_COLUMNS]
    pose = zip(column["desired_position"], column["desired_orientation"], strict=True)
    for k, (t, f, m, (p, o), q) in enumerate(
        zip(
            column["t_ns"],
            column["force"],
            column["moment"],
            pose,
            column["commanded_q"],
            strict=True,
        )
    ):
        yield INPUT_TOPIC, WrenchSample(t, (f[0], f[1], f[2]), (m[0], m[1], m[2]))
        yield STATE_TOPIC, ControllerSample(t, **{array: values[k] for array, values in state})
        yield DESIRED_TOPIC, PoseSample(t, (p[0], p[1], p[2]), (o[0], o[1], o[2], o[3]))
        yield COMMANDED_TOPIC, JointSample(t, q)
        yield LOOP_TOPIC, LoopTiming(t, **{name: values[k] for name, values in timing})


def event_samples(rows: Rows) -> Iterator[tuple[str, EventRecord]]:
    """``/events`` records of EVENT_DTYPE rows (their texts as the loop fitted them)."""
    columns = ("t_ns", "kind", "source", "detail", "axis", "value")
    for t_ns, kind, source, detail, axis, value in zip(
        *(rows[c].tolist() for c in columns), strict=True
    ):
        text = (source.decode(), detail.decode(), axis.decode())
        yield EVENTS_TOPIC, EventRecord(t_ns, EventKind(kind), *text, value=value)
