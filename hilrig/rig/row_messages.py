"""Rows to samples: the recorder turns the loop's rows (dtypes of :mod:`.records`) into the
recording's typed samples, each with its topic."""

from __future__ import annotations

from collections.abc import Iterator

from hilrig.recording import (
    ControllerSample,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    WrenchSample,
)
from hilrig.rig.rings import Rows

FT_TOPIC = "/ft/wrist"
JOINT_TOPIC = "/joint_states"
INPUT_TOPIC = "/controller/input"
STATE_TOPIC = "/controller/state"
DESIRED_TOPIC = "/trajectory/desired"
COMMANDED_TOPIC = "/trajectory/commanded"
LOOP_TOPIC = "/diagnostics/loop"
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


_TICK_COLUMNS = (
    "t_ns",
    "force",
    "moment",
    "offset",
    "offset_rate",
    "damping",
    "stiffness",
    "chi",
    "zeta",
    "contact",
    "desired_position",
    "desired_orientation",
    "commanded_q",
    "tick",
    "period_ns",
    "compute_ns",
    "lateness_ns",
    "overruns",
    "queue_drops",
)


def tick_samples(rows: Rows) -> Messages:
    """Per TICK_DTYPE row, in this order: ``/controller/input`` (the compensated wrist wrench
    in the base frame, N and N*m), ``/controller/state`` (all axes), ``/trajectory/desired``,
    ``/trajectory/commanded`` (positions only) and ``/diagnostics/loop``."""
    columns = zip(*(rows[c].tolist() for c in _TICK_COLUMNS), strict=True)
    for t, f, m, e, ed, b, k, chi, zeta, contact, p, o, q, *timing in columns:
        yield INPUT_TOPIC, WrenchSample(t, (f[0], f[1], f[2]), (m[0], m[1], m[2]))
        yield STATE_TOPIC, ControllerSample(t, f, e, ed, b, k, chi, zeta, contact)
        yield DESIRED_TOPIC, PoseSample(t, (p[0], p[1], p[2]), (o[0], o[1], o[2], o[3]))
        yield COMMANDED_TOPIC, JointSample(t, q)
        yield LOOP_TOPIC, LoopTiming(t, *timing)
