"""MCAP records read back from bytes, every field checked.

Each ``parse_*`` function reads one record at a file (or chunk) offset and returns its fields,
or raises :class:`BadRecordError` saying what is wrong: a field that runs past the record, a string
that is not UTF-8, bytes left over after the last field (records are parsed exactly, so a
damaged length is found), an unknown compression, a CRC that does not match, a time range
that runs backwards. A record whose length runs past the end of the buffer raises
:class:`CutRecordError` instead, which is what an unfinished file ends with.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from dataclasses import dataclass

from hilrig.recording.mcap_records import (
    RECORD_HEADER,
    SEAL_KEY,
    Channel,
    ChunkIndex,
    Metadata,
    Op,
    Schema,
    Statistics,
    seal_problem,
)

Buffer = mmap.mmap | bytes | memoryview
COMPRESSIONS = ("zstd", "lz4", "")
#: Larger decompressed chunks are refused as damaged (hilrig writes at most 8 MiB).
MAX_CHUNK_BYTES = 1 << 30
#: Records that belong to the summary section (after DataEnd), never to the data section.
SUMMARY_OPS = frozenset(
    {Op.CHUNK_INDEX, Op.ATTACHMENT_INDEX, Op.METADATA_INDEX, Op.STATISTICS, Op.SUMMARY_OFFSET}
)
KNOWN_OPS = frozenset(int(op) for op in Op)
KIND = {
    Op.HEADER: "header",
    Op.FOOTER: "footer",
    Op.SCHEMA: "schema",
    Op.CHANNEL: "channel",
    Op.MESSAGE: "message",
    Op.CHUNK: "chunk",
    Op.MESSAGE_INDEX: "message index",
    Op.CHUNK_INDEX: "chunk index",
    Op.ATTACHMENT: "attachment",
    Op.ATTACHMENT_INDEX: "attachment index",
    Op.STATISTICS: "statistics",
    Op.METADATA: "metadata",
    Op.METADATA_INDEX: "metadata index",
    Op.SUMMARY_OFFSET: "summary offset",
    Op.DATA_END: "data end",
}


class BadRecordError(Exception):
    """A record that does not parse; the message says why (one line)."""


class CutRecordError(BadRecordError):
    """A record whose length runs past the end of what was read."""


def kind(opcode: int) -> str:
    """A record kind for people: ``chunk record``, or ``record of unknown opcode 0x3f``."""
    name = KIND.get(Op(opcode)) if opcode in KNOWN_OPS else None
    return f"{name} record" if name else f"record of unknown opcode {opcode:#04x}"


class Cursor:
    """Reads little-endian fields of one record, never past ``end``."""

    def __init__(self, buf: Buffer, pos: int, end: int) -> None:
        self.buf, self.pos, self.end = buf, pos, end

    def take(self, fmt: str) -> tuple[int, ...]:
        size = struct.calcsize(fmt)
        if self.pos + size > self.end:
            raise BadRecordError("its fields run past its end")
        values = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return values

    def u(self, fmt: str) -> int:
        return self.take(fmt)[0]

    def raw(self, size: int) -> bytes:
        if self.pos + size > self.end:
            raise BadRecordError("its fields run past its end")
        data = bytes(self.buf[self.pos : self.pos + size])
        self.pos += size
        return data

    def string(self) -> str:
        try:
            return self.raw(self.u("<I")).decode()
        except UnicodeDecodeError:
            raise BadRecordError("a string in it is not UTF-8") from None

    def mapping(self) -> dict[str, str]:
        size = self.u("<I")
        end = self.pos + size
        if end > self.end:
            raise BadRecordError("its fields run past its end")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        if self.pos != end:
            raise BadRecordError("a map in it runs past its stated size")
        return out

    def done(self) -> None:
        if self.pos != self.end:
            raise BadRecordError(f"{self.end - self.pos} bytes are left after its last field")


def record_at(buf: Buffer, pos: int, limit: int) -> tuple[int, Cursor]:
    """The opcode of the record at ``pos`` and a cursor over its body (ending before
    ``limit``). Raises CutRecordError if it runs past ``limit``, BadRecordError for an unknown
    opcode."""
    if pos + RECORD_HEADER.size > limit:
        raise CutRecordError("the file ends inside its header")
    opcode, length = RECORD_HEADER.unpack_from(buf, pos)
    if opcode not in KNOWN_OPS:
        raise BadRecordError(f"unknown opcode {opcode:#04x}")
    body = pos + RECORD_HEADER.size
    if length > limit - body:
        raise CutRecordError(f"its length ({length} bytes) runs past the end of the file")
    return opcode, Cursor(buf, body, body + length)


def _time_range(start: int, end: int) -> None:
    if start > end:
        raise BadRecordError(f"its time range runs backwards ({start} > {end})")


@dataclass(frozen=True)
class ChunkHead:
    """A Chunk record's fields; its compressed data is ``[data_offset, + compressed_size)``."""

    start_ns: int
    end_ns: int
    uncompressed_size: int
    uncompressed_crc: int
    compression: str
    data_offset: int
    compressed_size: int


def parse_header(c: Cursor) -> tuple[str, str]:
    profile, library = c.string(), c.string()
    c.done()
    return profile, library


def parse_schema(c: Cursor) -> Schema:
    schema_id = c.u("<H")
    name, encoding = c.string(), c.string()
    schema = Schema(schema_id, name, encoding, c.raw(c.u("<I")))
    c.done()
    if schema_id == 0:
        raise BadRecordError("schema id 0 is reserved")
    return schema


def parse_channel(c: Cursor) -> Channel:
    channel_id, schema_id = c.take("<HH")
    topic, encoding = c.string(), c.string()
    channel = Channel(channel_id, schema_id, topic, encoding, c.mapping())
    c.done()
    _check_seal(channel)
    return channel


def _check_seal(record: Channel | Metadata) -> None:
    problem = seal_problem(record)
    if problem:
        raise BadRecordError(problem)


def parse_chunk(c: Cursor) -> ChunkHead:
    start, end, size, crc = c.take("<QQQI")
    compression = c.string()
    compressed_size = c.u("<Q")
    head = ChunkHead(start, end, size, crc, compression, c.pos, compressed_size)
    if compressed_size != c.end - c.pos:
        raise BadRecordError(
            f"its data size field ({compressed_size}) does not match its length ({c.end - c.pos})"
        )
    _check_chunk_fields(start, end, size, compression)
    return head


def _check_chunk_fields(start: int, end: int, size: int, compression: str) -> None:
    """(Its time range is checked against the session, by the index: a chunk whose times
    alone are damaged keeps its data.)"""
    if compression not in COMPRESSIONS:
        raise BadRecordError(f"unknown compression {compression!r}")
    if size > MAX_CHUNK_BYTES:
        raise BadRecordError(f"its decompressed size ({size} bytes) is impossible")


def parse_message_index(c: Cursor) -> tuple[int, int, int]:
    """``(channel id, offset of the first entry, entry count)``; entries are ``<QQ``."""
    channel_id, size = c.take("<HI")
    if size != c.end - c.pos or size % 16:
        raise BadRecordError(f"its entries' size ({size}) does not match its length")
    return channel_id, c.pos, size // 16


def parse_metadata(c: Cursor) -> tuple[str, dict[str, str]]:
    """The record's name and values (its seal checked and left out)."""
    name = c.string()
    values = c.mapping()
    c.done()
    _check_seal(Metadata(name, values))
    values.pop(SEAL_KEY, None)
    return name, values


@dataclass(frozen=True)
class AttachmentHead:
    """An Attachment record's fields, its CRC checked; data is ``[data_offset, + data_size)``."""

    log_time: int
    create_time: int
    name: str
    media_type: str
    data_offset: int
    data_size: int


def parse_attachment(c: Cursor) -> AttachmentHead:
    start = c.pos
    log_time, create_time = c.take("<QQ")
    name, media_type = c.string(), c.string()
    size = c.u("<Q")
    data_offset = c.pos
    c.raw(size)
    crc_at = c.pos
    crc = c.u("<I")
    c.done()
    if crc and zlib.crc32(c.buf[start:crc_at]) != crc:
        raise BadRecordError("CRC mismatch")
    return AttachmentHead(log_time, create_time, name, media_type, data_offset, size)


def parse_chunk_index(c: Cursor) -> ChunkIndex:
    start, end, offset, length = c.take("<QQQQ")
    size = c.u("<I")
    offsets_end = c.pos + size
    if offsets_end > c.end:
        raise BadRecordError("its fields run past its end")
    offsets: dict[int, int] = {}
    while c.pos < offsets_end:
        channel_id, at = c.take("<HQ")
        offsets[channel_id] = at
    if c.pos != offsets_end:
        raise BadRecordError("its message index offsets run past their stated size")
    index_length = c.u("<Q")
    compression = c.string()
    compressed, size = c.take("<QQ")
    c.done()
    _time_range(start, end)
    _check_chunk_fields(start, end, size, compression)
    return ChunkIndex(
        start, end, offset, length, offsets, index_length, compression, compressed, size
    )


@dataclass(frozen=True)
class IndexRef:
    """A MetadataIndex or AttachmentIndex: the record at ``offset`` (``length`` bytes) and its
    name; an attachment's times (ns), size and media type ("" for metadata)."""

    offset: int
    length: int
    name: str
    media_type: str = ""
    log_time: int = 0
    create_time: int = 0
    data_size: int = 0


def parse_metadata_index(c: Cursor) -> IndexRef:
    offset, length = c.take("<QQ")
    ref = IndexRef(offset, length, c.string())
    c.done()
    return ref


def parse_attachment_index(c: Cursor) -> IndexRef:
    offset, length, log_time, create_time, size = c.take("<QQQQQ")
    name, media_type = c.string(), c.string()
    c.done()
    return IndexRef(offset, length, name, media_type, log_time, create_time, size)


def parse_statistics(c: Cursor) -> Statistics:
    messages, schemas, channels, attachments, metadata, chunks, start, end = c.take("<QHIIIIQQ")
    size = c.u("<I")
    counts_end = c.pos + size
    if counts_end != c.end or (c.end - c.pos) % 10:
        raise BadRecordError("its channel message counts do not match its length")
    counts: dict[int, int] = {}
    while c.pos < c.end:
        channel_id, count = c.take("<HQ")
        counts[channel_id] = count
    _time_range(start, end)
    return Statistics(
        messages, schemas, channels, attachments, metadata, chunks, start, end, counts
    )


def parse_summary_offset(c: Cursor) -> tuple[int, int, int]:
    values = c.take("<BQQ")
    c.done()
    return values[0], values[1], values[2]


def parse_data_end(c: Cursor) -> int:
    crc = c.u("<I")
    c.done()
    return crc


def parse_footer(c: Cursor) -> tuple[int, int, int]:
    """``(summary start, summary offset start, summary CRC)``."""
    values = c.take("<QQI")
    c.done()
    return values[0], values[1], values[2]


def parse_message_head(c: Cursor) -> tuple[int, int, int, int]:
    """``(channel id, sequence, log time, publish time)`` of a Message record."""
    channel_id, sequence, log, publish = c.take("<HIQQ")
    return channel_id, sequence, log, publish
