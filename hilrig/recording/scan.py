"""Index an MCAP file: from its summary when the file is whole, by scanning when it is not.

:func:`index_file` returns where every schema, channel, chunk, metadata and attachment record
is, and - for a file whose writer was killed or whose copy was cut short - where it ends and
what the incomplete tail held. It never trusts a length it has not checked against the file
size, so any byte string gives either an index or one :class:`RecordingError` line.
"""

from __future__ import annotations

import mmap
import os
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from hilrig.errors import RecordingError
from hilrig.recording.mcap_records import MAGIC, RECORD_HEADER, Channel, Op, Schema
from hilrig.recording.session import utc_iso

_FOOTER_SIZE = RECORD_HEADER.size + 20


class _DamagedRecordError(RecordingError):
    """A record ends before its fields do; caught in this module, turned into what it means."""


#: What reading a damaged or cut record raises.
_DAMAGED = (_DamagedRecordError, struct.error, UnicodeDecodeError)


@dataclass(frozen=True)
class ChunkInfo:
    """A chunk record: file ``offset`` and total ``length`` of the record, log-time span (ns),
    where its compressed data starts and, per channel id, the file offset of its MessageIndex."""

    offset: int
    length: int
    start_ns: int
    end_ns: int
    compression: str
    data_offset: int
    compressed_size: int
    uncompressed_size: int
    uncompressed_crc: int
    message_index_offsets: Mapping[int, int]


@dataclass(frozen=True)
class RecordRef:
    """Where a metadata record is, and its name."""

    offset: int
    length: int
    name: str


@dataclass(frozen=True)
class AttachmentRef:
    """Where an attachment record is, and what its index says (times in ns, size in bytes)."""

    offset: int
    length: int
    name: str
    media_type: str
    log_time: int
    create_time: int
    data_size: int


@dataclass(frozen=True)
class Truncation:
    """Where an unfinished file stops being readable and what is known about the lost tail."""

    valid_end: int  # file offset after the last complete record
    file_size: int
    tail_opcode: int | None  # opcode of the incomplete record, if its first byte is there
    tail_start_ns: int | None  # log-time span of an incomplete chunk, when its header survived
    tail_end_ns: int | None

    @property
    def lost_bytes(self) -> int:
        return self.file_size - self.valid_end


@dataclass
class FileIndex:
    """What an MCAP file holds, by file offset. ``complete`` is True when the summary and footer
    were read and checked; ``truncation`` says where an unfinished file ends."""

    path: Path
    size: int
    profile: str
    library: str
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunks: list[ChunkInfo] = field(default_factory=list)
    metadata: list[RecordRef] = field(default_factory=list)
    attachments: list[AttachmentRef] = field(default_factory=list)
    loose_messages: list[int] = field(default_factory=list)  # offsets of messages outside chunks
    complete: bool = False
    truncation: Truncation | None = None


class _Cursor:
    """Reads little-endian fields from a buffer, raising _DamagedRecordError past ``end``."""

    def __init__(self, buf: mmap.mmap | bytes, pos: int, end: int) -> None:
        self.buf, self.pos, self.end = buf, pos, end

    def take(self, fmt: str) -> tuple[int, ...]:
        size = struct.calcsize(fmt)
        if self.pos + size > self.end:
            raise _DamagedRecordError("record ends early")
        values = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return values

    def u(self, fmt: str) -> int:
        return self.take(fmt)[0]

    def raw(self, size: int) -> bytes:
        if size < 0 or self.pos + size > self.end:
            raise _DamagedRecordError("record ends early")
        data = bytes(self.buf[self.pos : self.pos + size])
        self.pos += size
        return data

    def string(self) -> str:
        return self.raw(self.u("<I")).decode()

    def mapping(self) -> dict[str, str]:
        end = self.pos + self.u("<I")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        return out


def _add_definition(index: FileIndex, opcode: int, c: _Cursor, *, keep_known: bool = False) -> None:
    """Parse the Schema or Channel record (``opcode``) at ``c`` into ``index``; with
    ``keep_known`` a record of the same id already there stays."""
    if opcode == Op.SCHEMA:
        schema_id = c.u("<H")
        name, encoding = c.string(), c.string()
        schema = Schema(schema_id, name, encoding, c.raw(c.u("<I")))
        if not (keep_known and schema.id in index.schemas):
            index.schemas[schema.id] = schema
    else:
        channel_id, schema_id = c.take("<HH")
        topic, encoding = c.string(), c.string()
        channel = Channel(channel_id, schema_id, topic, encoding, c.mapping())
        if not (keep_known and channel.id in index.channels):
            index.channels[channel.id] = channel


def parse_chunk_head(c: _Cursor, offset: int, length: int) -> ChunkInfo:
    start, end, size, crc = c.take("<QQQI")
    compression = c.string()
    compressed_size = c.u("<Q")
    if c.pos + compressed_size > c.end:
        raise _DamagedRecordError("chunk data ends early")
    return ChunkInfo(offset, length, start, end, compression, c.pos, compressed_size, size, crc, {})


def open_mcap(path: str | os.PathLike[str]) -> tuple[Path, mmap.mmap]:
    """Map ``path`` read-only after checking it is a non-empty file starting with MCAP magic.

    Raises RecordingError naming the file: missing, a directory, empty, or not MCAP.
    """
    p = Path(path)
    try:
        with p.open("rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size == 0:
                raise RecordingError(f"{p}: empty file (0 bytes), not an MCAP recording")
            mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    except FileNotFoundError as err:
        raise RecordingError(f"{p}: no such file") from err
    except IsADirectoryError as err:
        raise RecordingError(f"{p}: is a directory, not an MCAP file") from err
    except PermissionError as err:
        raise RecordingError(f"{p}: permission denied") from err
    if mm[: len(MAGIC)] != MAGIC:
        mm.close()
        raise RecordingError(f"{p}: not an MCAP file (it does not start with the MCAP magic)")
    return p, mm


def _header(p: Path, mm: mmap.mmap) -> tuple[str, str, int]:
    try:
        opcode, length = RECORD_HEADER.unpack_from(mm, len(MAGIC))
        c = _Cursor(mm, len(MAGIC) + RECORD_HEADER.size, len(MAGIC) + RECORD_HEADER.size + length)
        if opcode != Op.HEADER or c.end > len(mm):
            raise _DamagedRecordError("not a header record")
        return c.string(), c.string(), c.end
    except _DAMAGED as err:
        raise RecordingError(f"{p}: MCAP header record is missing or damaged") from err


def index_file(path: str | os.PathLike[str]) -> FileIndex:
    """Index ``path``: schemas, channels, chunks, metadata and attachments, and truncation.

    Raises RecordingError (one line, naming the file) when it is not a readable MCAP file.
    """
    p, mm = open_mcap(path)
    try:
        return index_mapped(p, mm)
    finally:
        mm.close()


def index_mapped(path: Path, mm: mmap.mmap, *, use_summary: bool = True) -> FileIndex:
    """:func:`index_file` for a file already opened with :func:`open_mcap`; without
    ``use_summary`` the data section is scanned even when the summary is intact."""
    profile, library, data_start = _header(path, mm)
    index = FileIndex(path, len(mm), profile, library)
    if not (use_summary and _read_summary(mm, index)):
        _scan(mm, data_start, index)
    return index


def _read_summary(mm: mmap.mmap, index: FileIndex) -> bool:
    """Fill ``index`` from the summary section; False if there is no usable, CRC-valid one."""
    size = len(mm)
    footer_at = size - len(MAGIC) - _FOOTER_SIZE
    if footer_at < len(MAGIC) or mm[size - len(MAGIC) :] != MAGIC or mm[footer_at] != Op.FOOTER:
        return False
    summary_start, _, crc = struct.unpack_from("<QQI", mm, footer_at + 9)
    if summary_start == 0 or not len(MAGIC) < summary_start <= footer_at:
        return False
    if crc != 0:
        crc_end = footer_at + 9 + 16
        if zlib.crc32(mm[summary_start:crc_end]) != crc:
            return False
    chunks: list[ChunkInfo] = []
    pos = summary_start
    try:
        while pos < footer_at:
            opcode, length = RECORD_HEADER.unpack_from(mm, pos)
            c = _Cursor(mm, pos + RECORD_HEADER.size, pos + RECORD_HEADER.size + length)
            if c.end > footer_at:
                return False
            if opcode in (Op.SCHEMA, Op.CHANNEL):
                _add_definition(index, opcode, c)
            elif opcode == Op.CHUNK_INDEX:
                chunks.append(_chunk_from_index(mm, c))
            elif opcode in (Op.METADATA_INDEX, Op.ATTACHMENT_INDEX):
                _add_ref(index, opcode, c)
            pos = c.end
    except _DAMAGED:
        return False
    if not index.channels and chunks:
        return False  # a summary without channels cannot be read on its own
    index.chunks = sorted(chunks, key=lambda ch: ch.offset)
    index.complete = True
    return True


def _chunk_from_index(mm: mmap.mmap, c: _Cursor) -> ChunkInfo:
    start, end, chunk_offset, chunk_length = c.take("<QQQQ")
    offsets_end = c.pos + c.u("<I")
    message_index: dict[int, int] = {}
    while c.pos < offsets_end:
        channel_id, offset = c.take("<HQ")
        message_index[channel_id] = offset
    head = _Cursor(mm, chunk_offset + RECORD_HEADER.size, chunk_offset + chunk_length)
    info = parse_chunk_head(head, chunk_offset, chunk_length)
    return ChunkInfo(
        chunk_offset,
        chunk_length,
        start,
        end,
        info.compression,
        info.data_offset,
        info.compressed_size,
        info.uncompressed_size,
        info.uncompressed_crc,
        message_index,
    )


def _add_ref(index: FileIndex, opcode: int, c: _Cursor) -> None:
    offset, length = c.take("<QQ")
    if opcode == Op.METADATA_INDEX:
        index.metadata.append(RecordRef(offset, length, c.string()))
    else:
        log_time, create_time, size = c.take("<QQQ")
        name, media_type = c.string(), c.string()
        ref = AttachmentRef(offset, length, name, media_type, log_time, create_time, size)
        index.attachments.append(ref)


def _scan(mm: mmap.mmap, pos: int, index: FileIndex) -> None:
    """Walk the data section record by record, stopping at the first incomplete one."""
    size = len(mm)
    pending_index: dict[int, int] = {}
    while True:
        if pos + RECORD_HEADER.size > size:
            break
        opcode, length = RECORD_HEADER.unpack_from(mm, pos)
        end = pos + RECORD_HEADER.size + length
        if end > size or opcode not in Op.__members__.values():
            break
        c = _Cursor(mm, pos + RECORD_HEADER.size, end)
        try:
            if opcode != Op.MESSAGE_INDEX:
                _close_chunk(index, pending_index)  # the chunk's message indexes are complete
                pending_index = {}
            if opcode == Op.CHUNK:
                index.chunks.append(parse_chunk_head(c, pos, end - pos))
            elif opcode == Op.MESSAGE_INDEX and index.chunks:
                pending_index[c.u("<H")] = pos
            elif opcode in (Op.SCHEMA, Op.CHANNEL):
                _add_definition(index, opcode, c)
            elif opcode == Op.METADATA:
                index.metadata.append(RecordRef(pos, end - pos, c.string()))
            elif opcode == Op.ATTACHMENT:
                log_time, create_time = c.take("<QQ")
                name, media_type = c.string(), c.string()
                data_size = c.u("<Q")
                ref = AttachmentRef(
                    pos, end - pos, name, media_type, log_time, create_time, data_size
                )
                index.attachments.append(ref)
            elif opcode == Op.MESSAGE:
                index.loose_messages.append(pos)
        except _DAMAGED:
            break
        if opcode in (Op.DATA_END, Op.FOOTER):
            _close_chunk(index, pending_index)
            return  # the data section ended cleanly; only the summary was unusable
        pos = end
    # The last chunk's message indexes may be cut short: its messages are found by scanning.
    index.truncation = _truncation(mm, pos)


def _close_chunk(index: FileIndex, message_index: dict[int, int]) -> None:
    if index.chunks and message_index:
        last = index.chunks[-1]
        index.chunks[-1] = replace(last, message_index_offsets=message_index)


def _truncation(mm: mmap.mmap, pos: int) -> Truncation:
    size = len(mm)
    opcode = mm[pos] if pos < size else None
    start = end = None
    head = pos + RECORD_HEADER.size
    if opcode == Op.CHUNK and head + 16 <= size:
        start, end = struct.unpack_from("<QQ", mm, head)
    return Truncation(pos, size, opcode, start, end)


def add_definitions(index: FileIndex, data: bytes, positions: list[tuple[int, int]]) -> None:
    """Add the Schema and Channel records at ``(opcode, offset)`` in ``data`` (a chunk's
    records) to ``index``, keeping records already known."""
    for opcode, offset in positions:
        _, length = RECORD_HEADER.unpack_from(data, offset)
        cursor = _Cursor(data, offset + RECORD_HEADER.size, offset + RECORD_HEADER.size + length)
        try:
            _add_definition(index, opcode, cursor, keep_known=True)
        except _DAMAGED:
            continue  # a damaged definition leaves its channel unreadable, reported later


def describe_truncation(index: FileIndex) -> str:
    """One line: where an unfinished file ends, what was kept and what was lost."""
    t = index.truncation
    assert t is not None
    kept = index.chunks[-1].end_ns if index.chunks else None
    line = f"{index.path}: unfinished recording (no summary); {len(index.chunks)} complete chunks"
    line += f" kept, up to {utc_iso(kept)}" if kept is not None else " kept"
    if t.lost_bytes == 0:
        return line + "; nothing after them was written"
    line += f"; the last {t.lost_bytes} bytes (an incomplete record) were lost"
    if t.tail_start_ns is not None and t.tail_end_ns is not None:
        lost_s = (t.tail_end_ns - t.tail_start_ns) / 1e9
        line += f": messages from {utc_iso(t.tail_start_ns)} to {utc_iso(t.tail_end_ns)}"
        line += f" ({lost_s:.3f} s)"
    return line


def read_metadata(mm: mmap.mmap, ref: RecordRef) -> tuple[str, dict[str, str]]:
    """The name and key-value pairs of the metadata record ``ref``; RecordingError if damaged."""
    c = _Cursor(mm, ref.offset + RECORD_HEADER.size, ref.offset + ref.length)
    try:
        return c.string(), c.mapping()
    except _DAMAGED as err:
        raise RecordingError(
            f"metadata record {ref.name!r} at byte {ref.offset} is damaged"
        ) from err
