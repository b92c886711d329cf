"""Samples to MCAP Message records: one ``struct.Struct`` per channel, no generic serialisation.

A channel's layout is taken once from a prototype message of its :class:`.ChannelSpec` shape
(:func:`.cdr.prototype`); the bytes that never change (encapsulation header, frame id, names,
sequence lengths, padding) become constant ``s`` fields of the struct, the values become its
numeric fields, and encoding a sample is a single ``Struct.pack`` of record header and payload.
Events and strings carry free text, so their layout is worked out per message.
"""

from __future__ import annotations

import operator
import struct
from collections.abc import Callable

from hilrig.errors import RecordingError
from hilrig.recording.cdr import ColumnKind, Layout, layout_of, prototype
from hilrig.recording.mcap_records import MESSAGE_PREFIX, Op
from hilrig.recording.msgdef import MessageDefs, packaged_defs, short_name
from hilrig.recording.samples import (
    ControllerSample,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    TextSample,
    WrenchSample,
)
from hilrig.recording.schema import JOINT_ARRAYS, ChannelSpec, MessageType

_STRUCT_CODES = {
    "?": "?",
    "u1": "B",
    "i1": "b",
    "<i2": "h",
    "<u2": "H",
    "<i4": "i",
    "<u4": "I",
    "<i8": "q",
    "<u8": "Q",
    "<f4": "f",
    "<f8": "d",
}
_NS_PER_S = 1_000_000_000
_FREE_TEXT = (MessageType.EVENT, MessageType.STRING)  # their layout changes with the text

Values = tuple[float, ...]


class _Packer:
    """Packs the Message records of one layout with one ``struct.Struct``.

    The struct's fields are, in byte order, the record prefix and the payload: runs of constant
    bytes (``s`` fields: encapsulation header, strings, lengths, padding) between the values.
    :meth:`pack` lines its arguments up in that order with one ``itemgetter`` over
    ``constants + arguments``: no Python loop runs per message.
    """

    def __init__(self, channel_id: int, message: bytes, layout: Layout) -> None:
        fmt = [MESSAGE_PREFIX.format]
        constants: list[object] = [Op.MESSAGE, MESSAGE_PREFIX.size - 9 + len(message), channel_id]
        # Each struct field: (True, index in constants) or (False, index in the arguments).
        fields = [(True, 0), (True, 1), (True, 2), (False, 0), (False, 1), (False, 2)]
        argument, cursor = 3, 0  # values follow sequence, log time and publish time
        for column in layout.columns:
            if column.kind is ColumnKind.TEXT:
                continue
            codes = "iI" if column.kind is ColumnKind.TIME else _STRUCT_CODES[column.dtype]
            if column.offset > cursor:
                fmt.append(f"{column.offset - cursor}s")
                fields.append((True, len(constants)))
                constants.append(message[cursor : column.offset])
            for code in codes:
                fmt.append(code)
                fields.append((False, argument))
                argument += 1
            cursor = column.offset + struct.calcsize("<" + codes)
        fmt.append(f"{len(message) - cursor}s")
        fields.append((True, len(constants)))
        constants.append(message[cursor:])
        self.struct = struct.Struct("".join(fmt))
        self.constants = tuple(constants)
        n = len(constants)
        self.order = operator.itemgetter(*(i if constant else n + i for constant, i in fields))

    def pack(self, sequence: int, log_ns: int, publish_ns: int, values: Values) -> bytes:
        """The record; ``values`` are the message's numbers in field order (a time: sec, ns)."""
        arguments = self.order((*self.constants, sequence, log_ns, publish_ns, *values))
        return self.struct.pack(*arguments)


class ChannelEncoder:
    """Encodes the samples of one channel into complete MCAP Message records (bytes)."""

    def __init__(self, channel_id: int, spec: ChannelSpec) -> None:
        self.channel_id = channel_id
        self.spec = spec
        self.defs: MessageDefs = packaged_defs(spec.type.value)
        self.root = short_name(spec.type.value)
        self._values = _value_function(spec)
        self._packer: _Packer | None = None
        if spec.type not in _FREE_TEXT:
            message = prototype(self.defs, self.root, spec.shape)
            self._packer = _Packer(channel_id, message, layout_of(self.defs, self.root, message))

    def encode(self, sample: Sample, sequence: int, log_ns: int, publish_ns: int) -> bytes:
        """The Message record of ``sample``; its header stamp is ``log_ns``.

        Raises RecordingError when the sample does not fit the channel (type, array lengths,
        values out of range of their fields).
        """
        values = divmod(log_ns, _NS_PER_S) + self._values(sample)
        packer = self._packer or self._text_packer(sample)
        try:
            return packer.pack(sequence, log_ns, publish_ns, values)
        except struct.error as err:
            raise RecordingError(f"channel {self.spec.topic}: cannot encode sample: {err}") from err

    def check(self, sample: Sample) -> None:
        """Raise RecordingError if ``sample`` does not fit the channel (type, array lengths)."""
        self._values(sample)

    def _text_packer(self, sample: Sample) -> _Packer:
        """A packer for this message's own text (events and strings change length)."""
        if isinstance(sample, TextSample):
            shape: dict[str, object] = {"data": sample.text}
        else:
            assert isinstance(sample, EventRecord)  # checked by _value_function
            shape = {"source": sample.source, "detail": sample.detail, "axis": sample.axis}
        message = prototype(self.defs, self.root, shape)
        return _Packer(self.channel_id, message, layout_of(self.defs, self.root, message))


def _value_function(spec: ChannelSpec) -> Callable[[Sample], Values]:
    """The function listing a sample's values (after the header stamp) in schema order."""
    n = len(spec.names)
    topic = spec.topic

    def wrong(sample: Sample, expected: type) -> RecordingError:
        got = type(sample).__name__
        return RecordingError(f"channel {topic} takes {expected.__name__}, got {got}")

    def wrench(s: Sample) -> Values:
        if not isinstance(s, WrenchSample):
            raise wrong(s, WrenchSample)
        return (*s.force, *s.torque)

    lengths = tuple(n if a in spec.arrays else 0 for a in JOINT_ARRAYS)

    def joints(s: Sample) -> Values:
        if not isinstance(s, JointSample):
            raise wrong(s, JointSample)
        if (len(s.position), len(s.velocity), len(s.effort)) != lengths:
            raise RecordingError(f"channel {topic}: joint arrays must have lengths {lengths}")
        return (*s.position, *s.velocity, *s.effort)

    def pose(s: Sample) -> Values:
        if not isinstance(s, PoseSample):
            raise wrong(s, PoseSample)
        return (*s.position, *s.orientation)

    def controller(s: Sample) -> Values:
        if not isinstance(s, ControllerSample):
            raise wrong(s, ControllerSample)
        arrays = (s.force, s.offset, s.offset_rate, s.damping, s.stiffness, s.chi, s.zeta)
        if any(len(a) != n for a in arrays) or len(s.contact_state) != n:
            raise RecordingError(f"channel {topic}: every controller array needs {n} entries")
        return (
            *s.force,
            *s.offset,
            *s.offset_rate,
            *s.damping,
            *s.stiffness,
            *s.chi,
            *s.zeta,
            *s.contact_state,
        )

    def event(s: Sample) -> Values:
        if not isinstance(s, EventRecord):
            raise wrong(s, EventRecord)
        return (int(s.kind), s.value)

    def text(s: Sample) -> Values:
        if not isinstance(s, TextSample):
            raise wrong(s, TextSample)
        return ()

    def loop(s: Sample) -> Values:
        if not isinstance(s, LoopTiming):
            raise wrong(s, LoopTiming)
        return (s.tick, s.period_ns, s.compute_ns, s.lateness_ns, s.overruns, s.queue_drops)

    functions: dict[MessageType, Callable[[Sample], Values]] = {
        MessageType.WRENCH: wrench,
        MessageType.JOINT_STATE: joints,
        MessageType.POSE: pose,
        MessageType.CONTROLLER_STATE: controller,
        MessageType.EVENT: event,
        MessageType.LOOP_DIAGNOSTICS: loop,
        MessageType.STRING: text,
    }
    return functions[spec.type]
