"""MCAP records (https://mcap.dev/spec) as bytes: opcodes, frozen record types, serialisation.

Only what hilrig writes and recovers is here; the hot path (messages inside chunks) is encoded
in :mod:`hilrig.recording.encode` and read in :mod:`hilrig.recording.columns`. Every record is
``opcode:u8 length:u64 body``; strings are ``u32`` length-prefixed UTF-8.
"""

from __future__ import annotations

import enum
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TypeVar

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEADER = struct.Struct("<BQ")
#: Size of a Message record before its data: opcode, length, channel, sequence, log and
#: publish time.
MESSAGE_PREFIX = struct.Struct("<BQHIQQ")


class Op(enum.IntEnum):
    HEADER = 0x01
    FOOTER = 0x02
    SCHEMA = 0x03
    CHANNEL = 0x04
    MESSAGE = 0x05
    CHUNK = 0x06
    MESSAGE_INDEX = 0x07
    CHUNK_INDEX = 0x08
    ATTACHMENT = 0x09
    ATTACHMENT_INDEX = 0x0A
    STATISTICS = 0x0B
    METADATA = 0x0C
    METADATA_INDEX = 0x0D
    SUMMARY_OFFSET = 0x0E
    DATA_END = 0x0F


def _str(value: str) -> bytes:
    raw = value.encode()
    return struct.pack("<I", len(raw)) + raw


def _map(entries: Mapping[str, str]) -> bytes:
    body = b"".join(_str(k) + _str(v) for k, v in entries.items())
    return struct.pack("<I", len(body)) + body


def record(op: Op, body: bytes) -> bytes:
    """One record: opcode, body length, body."""
    return RECORD_HEADER.pack(op, len(body)) + body


@dataclass(frozen=True)
class Schema:
    id: int
    name: str
    encoding: str
    data: bytes

    def encode(self) -> bytes:
        body = struct.pack("<H", self.id) + _str(self.name) + _str(self.encoding)
        return record(Op.SCHEMA, body + struct.pack("<I", len(self.data)) + self.data)


@dataclass(frozen=True)
class Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: Mapping[str, str]

    def encode(self) -> bytes:
        body = struct.pack("<HH", self.id, self.schema_id) + _str(self.topic)
        return record(Op.CHANNEL, body + _str(self.message_encoding) + _map(self.metadata))


@dataclass(frozen=True)
class Metadata:
    name: str
    metadata: Mapping[str, str]

    def encode(self) -> bytes:
        return record(Op.METADATA, _str(self.name) + _map(self.metadata))


#: MCAP gives Channel and Metadata records no CRC; hilrig adds one as their last key: the
#: CRC-32 (8 hex digits) of the record as it would be without that key.
SEAL_KEY = "hilrig.crc32"


Sealable = TypeVar("Sealable", Channel, Metadata)


def sealed(record: Sealable) -> Sealable:
    """``record`` with its :data:`SEAL_KEY`."""
    crc = f"{zlib.crc32(record.encode()):08x}"
    return replace(record, metadata={**record.metadata, SEAL_KEY: crc})


def seal_problem(record: Channel | Metadata) -> str:
    """Why ``record``'s seal does not hold ("" when it does, or when it has none)."""
    values = dict(record.metadata)
    crc = values.pop(SEAL_KEY, None)
    if crc is None or crc == f"{zlib.crc32(replace(record, metadata=values).encode()):08x}":
        return ""
    return "its CRC (key hilrig.crc32) does not match"


@dataclass(frozen=True)
class Attachment:
    """A file stored in the recording; times are int64 ns (``create_time`` 0 when unknown)."""

    name: str
    media_type: str
    data: bytes
    log_time: int = 0
    create_time: int = 0

    def encode(self) -> bytes:
        body = struct.pack("<QQ", self.log_time, self.create_time) + _str(self.name)
        body += _str(self.media_type) + struct.pack("<Q", len(self.data)) + self.data
        return record(Op.ATTACHMENT, body + struct.pack("<I", zlib.crc32(body)))


@dataclass(frozen=True)
class ChunkIndex:
    """Where a chunk is and what it holds; ``message_index_offsets`` maps channel id to the file
    offset of that channel's MessageIndex record after the chunk."""

    message_start_time: int
    message_end_time: int
    chunk_start_offset: int
    chunk_length: int
    message_index_offsets: Mapping[int, int]
    message_index_length: int
    compression: str
    compressed_size: int
    uncompressed_size: int

    def encode(self) -> bytes:
        offsets = b"".join(struct.pack("<HQ", k, v) for k, v in self.message_index_offsets.items())
        body = struct.pack(
            "<QQQQI",
            self.message_start_time,
            self.message_end_time,
            self.chunk_start_offset,
            self.chunk_length,
            len(offsets),
        )
        body += offsets + struct.pack("<Q", self.message_index_length) + _str(self.compression)
        body += struct.pack("<QQ", self.compressed_size, self.uncompressed_size)
        return record(Op.CHUNK_INDEX, body)


def header(profile: str, library: str) -> bytes:
    return record(Op.HEADER, _str(profile) + _str(library))


def chunk_head(
    *,
    start_ns: int,
    end_ns: int,
    uncompressed_size: int,
    uncompressed_crc: int,
    compression: str,
    compressed_size: int,
) -> bytes:
    """A Chunk record up to its data: the caller writes the ``compressed_size`` bytes after it."""
    body = struct.pack("<QQQI", start_ns, end_ns, uncompressed_size, uncompressed_crc)
    body += _str(compression) + struct.pack("<Q", compressed_size)
    return RECORD_HEADER.pack(Op.CHUNK, len(body) + compressed_size) + body


def message_index(channel_id: int, entries: bytes) -> bytes:
    """A MessageIndex record; ``entries`` is packed ``<QQ`` (log time, offset in chunk) pairs."""
    return record(Op.MESSAGE_INDEX, struct.pack("<HI", channel_id, len(entries)) + entries)


def attachment_index(
    offset: int,
    length: int,
    *,
    name: str,
    media_type: str,
    log_time: int,
    create_time: int,
    data_size: int,
) -> bytes:
    """The AttachmentIndex of the attachment record at ``offset`` (``length`` bytes)."""
    body = struct.pack("<QQQQQ", offset, length, log_time, create_time, data_size)
    return record(Op.ATTACHMENT_INDEX, body + _str(name) + _str(media_type))


def metadata_index(offset: int, length: int, name: str) -> bytes:
    return record(Op.METADATA_INDEX, struct.pack("<QQ", offset, length) + _str(name))


def data_end(crc: int) -> bytes:
    return record(Op.DATA_END, struct.pack("<I", crc))


@dataclass(frozen=True)
class Statistics:
    """Counts and log-time span (int64 ns) of a recording, per the Statistics record."""

    message_count: int
    schema_count: int
    channel_count: int
    attachment_count: int
    metadata_count: int
    chunk_count: int
    message_start_time: int
    message_end_time: int
    channel_message_counts: Mapping[int, int]

    def encode(self) -> bytes:
        counts = b"".join(struct.pack("<HQ", k, v) for k, v in self.channel_message_counts.items())
        body = struct.pack(
            "<QHIIIIQQI",
            self.message_count,
            self.schema_count,
            self.channel_count,
            self.attachment_count,
            self.metadata_count,
            self.chunk_count,
            self.message_start_time,
            self.message_end_time,
            len(counts),
        )
        return record(Op.STATISTICS, body + counts)


def summary_offset(op: Op, start: int, length: int) -> bytes:
    return record(Op.SUMMARY_OFFSET, struct.pack("<BQQ", op, start, length))


def footer(summary_start: int, summary_offset_start: int, summary: bytes | bytearray) -> bytes:
    """The Footer; its CRC covers the summary section and the footer fields before the CRC."""
    fields = RECORD_HEADER.pack(Op.FOOTER, 20) + struct.pack(
        "<QQ", summary_start, summary_offset_start
    )
    return fields + struct.pack("<I", zlib.crc32(fields, zlib.crc32(summary)))


def data_end_and_summary(
    offset: int,
    *,
    schemas: list[Schema],
    channels: list[Channel],
    statistics: Statistics,
    chunk_indexes: list[ChunkIndex],
    attachment_indexes: list[bytes],
    metadata_indexes: list[bytes],
    data_crc: int,
) -> bytes:
    """Everything after the last data record: DataEnd (with ``data_crc``, the CRC-32 of every
    byte before it), the summary section (schemas, channels, statistics and indexes, one group
    per record type), summary offsets, footer and magic.

    ``offset`` is the file offset the returned bytes will be written at.
    """
    end = data_end(data_crc)
    summary_start = offset + len(end)
    groups: list[tuple[Op, bytes]] = [
        (Op.SCHEMA, b"".join(s.encode() for s in schemas)),
        (Op.CHANNEL, b"".join(c.encode() for c in channels)),
        (Op.STATISTICS, statistics.encode()),
        (Op.CHUNK_INDEX, b"".join(c.encode() for c in chunk_indexes)),
        (Op.ATTACHMENT_INDEX, b"".join(attachment_indexes)),
        (Op.METADATA_INDEX, b"".join(metadata_indexes)),
    ]
    summary = bytearray()
    offsets = bytearray()
    for op, group in groups:
        if group:
            offsets += summary_offset(op, summary_start + len(summary), len(group))
            summary += group
    summary_offset_start = summary_start + len(summary)
    summary += offsets
    return end + bytes(summary) + footer(summary_start, summary_offset_start, summary) + MAGIC
