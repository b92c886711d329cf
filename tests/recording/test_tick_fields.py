"""The tick row has one definition (``TICK_FIELDS``): the rig's ring dtype, the schema's
ControllerState arrays, the message definition and the recorder's samples all follow it."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from hilrig.recording import ControllerSample, LoopTiming, MessageType
from hilrig.recording.msgdef import packaged_message
from hilrig.recording.schema import AXES, CONTROLLER_ARRAYS, TICK_FIELDS
from hilrig.rig import TICK_DTYPE
from hilrig.rig.row_messages import LOOP_TOPIC, STATE_TOPIC, tick_samples

# The names the loop writes: they must not change under it.
TICK_NAMES = (
    "t_ns",
    "tick",
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
    "period_ns",
    "compute_ns",
    "lateness_ns",
    "overruns",
    "queue_drops",
)


def test_the_ring_dtype_is_built_from_the_table() -> None:
    assert TICK_DTYPE.names == TICK_NAMES == tuple(f.name for f in TICK_FIELDS)
    for f in TICK_FIELDS:
        assert TICK_DTYPE[f.name].base == np.dtype(f.kind), f.name
        assert TICK_DTYPE[f.name].shape == ((f.size,) if f.size else ()), f.name
        if f.state:
            assert f.size == AXES, f.name


def test_the_schema_arrays_are_the_per_axis_fields_in_the_messages_order() -> None:
    state_fields = tuple(f.state for f in TICK_FIELDS if f.state)
    assert state_fields == CONTROLLER_ARRAYS
    assert tuple(f.name for f in fields(ControllerSample))[1:] == CONTROLLER_ARRAYS
    message = packaged_message(MessageType.CONTROLLER_STATE.value)
    assert tuple(f.name for f in message.fields)[3:] == CONTROLLER_ARRAYS


def test_tick_samples_read_every_field_by_name_whatever_the_field_order() -> None:
    shuffled = np.dtype([(name, TICK_DTYPE[name]) for name in reversed(TICK_NAMES)])
    rows = np.zeros(2, dtype=shuffled)
    for k, name in enumerate(TICK_NAMES):
        rows[name] = k + 1 + np.arange(2)[(...,) + (None,) * TICK_DTYPE[name].ndim]
    messages = list(tick_samples(rows))
    assert [topic for topic, _ in messages][:5] == [
        "/controller/input",
        STATE_TOPIC,
        "/trajectory/desired",
        "/trajectory/commanded",
        LOOP_TOPIC,
    ]
    state = messages[1][1]
    timing = messages[4][1]
    assert isinstance(state, ControllerSample) and isinstance(timing, LoopTiming)
    index = {name: k + 1 for k, name in enumerate(TICK_NAMES)}
    for f in TICK_FIELDS:
        if f.state:
            assert list(getattr(state, f.state)) == [index[f.name]] * AXES, f.name
    for name in (f.name for f in fields(LoopTiming)):
        assert getattr(timing, name) == index[name], name
    assert messages[6][1].t_ns == index["t_ns"] + 1  # the second row's
