"""Fixed layouts of CDR-encoded ROS 2 messages: where each value sits in the serialized bytes.

ROS 2 messages in MCAP are CDR (XCDR1) with a 4-byte encapsulation header; primitives are aligned
to their size (at most 8) relative to the end of that header, strings and sequences carry a
uint32 length. When every string and sequence length is the same in all messages of a channel
(frame ids, joint names and joint counts do not change during a session), every value sits at
the same byte offset in every message: the channel has a *fixed layout*. The reader then views a
whole channel as numpy columns, and the writer encodes a message with one ``struct.Struct``.

:func:`layout_of` finds the layout of a serialized message; :func:`prototype` serializes a
message of a given shape with zero values, so the writer can take the layout from it.
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hilrig.recording.msgdef import PRIMITIVE_TYPES, TIME_TYPES, MessageDefs, short_name

ENCAPSULATION_CDR_LE = b"\x00\x01\x00\x00"
HEADER_SIZE = len(ENCAPSULATION_CDR_LE)

#: numpy dtype of each fixed-size primitive (``char`` is uint8 in ROS 2).
DTYPES: Mapping[str, str] = {
    "bool": "?",
    "byte": "u1",
    "char": "u1",
    "int8": "i1",
    "uint8": "u1",
    "int16": "<i2",
    "uint16": "<u2",
    "int32": "<i4",
    "uint32": "<u4",
    "int64": "<i8",
    "uint64": "<u8",
    "float32": "<f4",
    "float64": "<f8",
}
_SIZES = {name: int(dtype[-1]) if dtype[-1].isdigit() else 1 for name, dtype in DTYPES.items()}


class LayoutError(ValueError):
    """A message has no fixed layout this module understands (big endian, wstring, short)."""


class ColumnKind(enum.Enum):
    VALUE = "value"  # one primitive value of dtype at offset
    TIME = "time"  # builtin_interfaces/Time or Duration: int32 sec, uint32 nanosec -> int64 ns
    TEXT = "text"  # a string, the same in every message of the channel


@dataclass(frozen=True)
class Column:
    """One output column: ``name`` (a dotted field path, ``_i`` per array element), byte
    ``offset`` in the serialized message (encapsulation header included), its kind and dtype.

    TIME columns are named ``<path>_ns`` and hold int64 nanoseconds; TEXT columns carry ``text``.
    """

    name: str
    offset: int
    kind: ColumnKind
    dtype: str
    text: str = ""


@dataclass(frozen=True)
class Layout:
    """The fixed layout of a channel: message ``size`` in bytes, its columns in field order, and
    the ``fixed`` byte ranges (lengths and string contents) that must match in every message."""

    size: int
    columns: tuple[Column, ...]
    fixed: tuple[tuple[int, int], ...]


def _align(pos: int, size: int) -> int:
    return pos + (-pos % size)


class _Walk:
    """Walks a message definition over serialized bytes (``data``) or, when synthesizing, over a
    growing buffer whose strings and sequence lengths come from ``shape``."""

    def __init__(
        self, defs: MessageDefs, data: bytes | None, shape: Mapping[str, object] | None
    ) -> None:
        self.defs = defs
        self.data = data
        self.shape = shape or {}
        self.out = bytearray()
        self.pos = 0  # relative to the end of the encapsulation header
        self.columns: list[Column] = []
        self.fixed: list[tuple[int, int]] = []

    def _take(self, size: int, alignment: int) -> int:
        start = _align(self.pos, alignment)
        if self.data is None:
            self.out.extend(bytes(start - self.pos + size))
        elif HEADER_SIZE + start + size > len(self.data):
            raise LayoutError("message is shorter than its definition")
        self.pos = start + size
        return start

    def _uint32(self, value_if_synth: int) -> int:
        start = self._take(4, 4)
        self.fixed.append((HEADER_SIZE + start, HEADER_SIZE + start + 4))
        if self.data is None:
            struct.pack_into("<I", self.out, start, value_if_synth)
            return value_if_synth
        return int(struct.unpack_from("<I", self.data, HEADER_SIZE + start)[0])

    def _string(self, path: str, value_if_synth: str) -> None:
        encoded = value_if_synth.encode() + b"\0"
        length = self._uint32(len(encoded))
        start = self._take(length, 1)
        self.fixed.append((HEADER_SIZE + start, HEADER_SIZE + start + length))
        if self.data is None:
            self.out[start : start + length] = encoded
            text = value_if_synth
        else:
            raw = self.data[HEADER_SIZE + start : HEADER_SIZE + start + length]
            text = raw.rstrip(b"\0").decode("utf-8", errors="replace")
        self.columns.append(Column(path, HEADER_SIZE + start, ColumnKind.TEXT, "", text))

    def _scalar(self, type_name: str, path: str, synth: object) -> None:
        if type_name == "string":
            self._string(path, synth if isinstance(synth, str) else "")
        elif type_name == "wstring":
            raise LayoutError("wstring fields have no fixed layout here")
        elif type_name in TIME_TYPES:
            start = self._take(8, 4)
            self.columns.append(Column(f"{path}_ns", HEADER_SIZE + start, ColumnKind.TIME, "<i8"))
        elif type_name in PRIMITIVE_TYPES:
            size = _SIZES[type_name]
            start = self._take(size, size)
            self.columns.append(
                Column(path, HEADER_SIZE + start, ColumnKind.VALUE, DTYPES[type_name])
            )
        else:
            self.message(type_name, f"{path}.")

    def message(self, type_name: str, prefix: str = "") -> None:
        definition = self.defs.get(short_name(type_name))
        if definition is None:
            raise LayoutError(f"schema lacks the definition of {type_name}")
        if not definition.fields:  # ROS 2 gives an empty message one uint8 member
            self._take(1, 1)
        for field in definition.fields:
            path = prefix + field.name
            spec = self.shape.get(path)
            if field.array_size is None:
                self._scalar(field.type, path, spec)
                continue
            items: Sequence[object] = spec if isinstance(spec, (list, tuple)) else ()
            count = field.array_size
            if field.is_sequence:
                synth_count = spec if isinstance(spec, int) else len(items)
                count = self._uint32(synth_count)
            for i in range(count):
                self._scalar(field.type, f"{path}_{i}", items[i] if i < len(items) else None)


def layout_of(defs: MessageDefs, root: str, message: bytes) -> Layout:
    """The layout of ``message`` (serialized ``root``, with its encapsulation header).

    Raises LayoutError when the message is not little-endian XCDR1 or does not match ``defs``.
    """
    if message[:2] != ENCAPSULATION_CDR_LE[:2]:
        raise LayoutError("not little-endian CDR")
    walk = _Walk(defs, message, None)
    walk.message(root)
    return Layout(len(message), tuple(walk.columns), _merge(walk.fixed))


def prototype(defs: MessageDefs, root: str, shape: Mapping[str, object]) -> bytes:
    """Serialize ``root`` with every number zero and the strings and sequence lengths of
    ``shape`` (field path -> str, list of str, or sequence length), e.g.
    ``{"header.frame_id": "base", "name": ["j1", "j2"], "position": 2}``."""
    walk = _Walk(defs, None, shape)
    walk.message(root)
    return ENCAPSULATION_CDR_LE + bytes(walk.out)


def _merge(ranges: list[tuple[int, int]]) -> tuple[tuple[int, int], ...]:
    merged: list[tuple[int, int]] = []
    for start, end in sorted(ranges):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(end, merged[-1][1]))
        else:
            merged.append((start, end))
    return tuple(merged)
