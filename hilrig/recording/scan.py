"""Index an MCAP file: from its summary when that is whole, by scanning the data section when not.

:func:`index_file` returns where every schema, channel, chunk, metadata and attachment record
is, the metadata's values, and what is damaged: every record is parsed exactly
(:mod:`.parse`), the summary's CRC is checked and every record it points to is checked against
it, times are checked against what the session allows, and a file whose writer was killed says
where it ends. A damaged record is skipped and the scan goes on at the next record that parses
(:mod:`.resync`), so any byte string gives an index with its damage listed, or - when it is not
an MCAP file at all - one :class:`RecordingError` line.
"""

from __future__ import annotations

import mmap
import os
from dataclasses import replace
from pathlib import Path

from hilrig.errors import RecordingError
from hilrig.recording import parse as p
from hilrig.recording.definitions import check_definitions, written_by_hilrig
from hilrig.recording.file_index import ChunkInfo, FileIndex, Truncation
from hilrig.recording.mcap_records import MAGIC, RECORD_HEADER, Op
from hilrig.recording.resync import next_record
from hilrig.recording.session import SESSION_METADATA, SessionInfo, TimeWindow
from hilrig.recording.summary import Summary


def open_mcap(path: str | os.PathLike[str]) -> tuple[Path, mmap.mmap]:
    """Map ``path`` read-only after checking it is a non-empty file starting with MCAP magic.

    Raises RecordingError naming the file: missing, a directory, empty, or not MCAP.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size == 0:
                raise RecordingError(f"{path}: empty file (0 bytes), not an MCAP recording")
            mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    except FileNotFoundError as err:
        raise RecordingError(f"{path}: no such file") from err
    except IsADirectoryError as err:
        raise RecordingError(f"{path}: is a directory, not an MCAP file") from err
    except PermissionError as err:
        raise RecordingError(f"{path}: permission denied") from err
    except OSError as err:
        raise RecordingError(f"{path}: cannot be read ({err.strerror})") from err
    if mm[: len(MAGIC)] != MAGIC:
        mm.close()
        raise RecordingError(f"{path}: not an MCAP file (it does not start with the MCAP magic)")
    return path, mm


def index_file(path: str | os.PathLike[str]) -> FileIndex:
    """Index ``path`` (see the module docstring). Raises RecordingError (one line, naming the
    file) when it is not an MCAP file at all."""
    opened, mm = open_mcap(path)
    try:
        return index_mapped(opened, mm)
    finally:
        mm.close()


def index_mapped(path: Path, mm: mmap.mmap, *, use_summary: bool = True) -> FileIndex:
    """:func:`index_file` for a file already opened with :func:`open_mcap`; without
    ``use_summary`` the data section is scanned even when the summary is whole."""
    index = FileIndex(path, len(mm))
    data_start = _header(mm, index)
    summary = Summary.read(mm, index)
    if summary is not None and use_summary:
        summary.fill(mm, index)
    else:
        _scan(mm, data_start, index)
    if summary is not None and not use_summary:
        summary.compare_definitions(index)
        summary.compare_metadata(index)
    index.complete = summary is not None
    index.statistics = summary.statistics if summary is not None else None
    _check_metadata(index)
    check_definitions(index)
    _check_times(index)
    return index


def _header(mm: mmap.mmap, index: FileIndex) -> int:
    """Read the Header record into ``index``; where the next record starts."""
    pos = len(MAGIC)
    try:
        opcode, c = p.record_at(mm, pos, len(mm))
        if opcode != Op.HEADER:
            raise p.BadRecordError(f"it is a {p.kind(opcode)}, not a header")
        index.profile, index.library = p.parse_header(c)
        return c.end
    except p.BadRecordError as err:
        start = next_record(mm, pos + 1, len(mm))
        end = len(mm) if start is None else start
        index.damaged("header record", pos, str(err), end)
        return end


def _scan(mm: mmap.mmap, pos: int, index: FileIndex) -> None:
    """Walk the data section record by record; a damaged record is skipped to the next one
    that parses, a record cut by the end of the file ends the walk."""
    limit = index.data_end if index.data_end is not None else len(mm)
    indexing: ChunkInfo | None = None  # the chunk whose message indexes may follow
    while pos < limit:
        try:
            opcode, c = p.record_at(mm, pos, limit)
            if opcode in p.SUMMARY_OPS or opcode == Op.FOOTER:
                index.damaged("data end record", pos, "missing: the summary starts here")
                return
            if opcode == Op.MESSAGE_INDEX:
                channel_id, _, _ = p.parse_message_index(c)
                if indexing is None:
                    raise p.BadRecordError("it follows no chunk")
                indexing.message_index_offsets.setdefault(channel_id, pos)
            else:
                indexing = _add_record(index, opcode, c, pos)
        except p.BadRecordError as err:
            if indexing is not None and mm[pos] == Op.MESSAGE_INDEX:
                index.incomplete_indexes.add(indexing.offset)  # one of its indexes is lost
            else:
                indexing = None
            after = next_record(mm, pos + 1, limit)
            if after is None and isinstance(err, p.CutRecordError) and index.data_end is None:
                index.truncation = _truncation(mm, pos, limit)
                return
            index.damaged(_what(mm, pos), pos, str(err), after or limit)
            if after is None:
                return
            pos = after
            continue
        if opcode == Op.DATA_END:
            return
        pos = c.end
    if index.data_end is None:
        index.truncation = _truncation(mm, pos, limit)


def _what(mm: mmap.mmap, pos: int) -> str:
    """The kind of a damaged record, with its name when that much of it is readable."""
    opcode = mm[pos]
    if opcode not in p.KNOWN_OPS:
        return "unreadable bytes"
    what = p.kind(opcode)
    if opcode in (Op.METADATA, Op.SCHEMA, Op.CHANNEL):
        try:
            c = p.Cursor(mm, pos + RECORD_HEADER.size, len(mm))
            if opcode == Op.METADATA:
                return f"{what} {c.string()!r}"
            return f"{p.KIND[Op(opcode)]} record {c.u('<H')}"
        except p.BadRecordError:
            return what
    return what


def _add_record(index: FileIndex, opcode: int, c: p.Cursor, pos: int) -> ChunkInfo | None:
    """Add the record at ``pos`` to ``index``; the chunk, if it is one."""
    if opcode == Op.CHUNK:
        head = p.parse_chunk(c)
        chunk = ChunkInfo(
            pos,
            c.end - pos,
            head.start_ns,
            head.end_ns,
            head.compression,
            head.data_offset,
            head.compressed_size,
            head.uncompressed_size,
            head.uncompressed_crc,
            {},
        )
        index.chunks.append(chunk)
        return chunk
    if opcode == Op.SCHEMA:
        schema = p.parse_schema(c)
        index.schemas.setdefault(schema.id, schema)
        index.definition_offsets.setdefault((opcode, schema.id), pos)
    elif opcode == Op.CHANNEL:
        channel = p.parse_channel(c)
        index.channels.setdefault(channel.id, channel)
        index.definition_offsets.setdefault((opcode, channel.id), pos)
    elif opcode == Op.METADATA:
        name, values = p.parse_metadata(c)
        index.metadata.append(p.IndexRef(pos, c.end - pos, name))
        index.values.setdefault(name, {}).update(values)
    elif opcode == Op.ATTACHMENT:
        a = p.parse_attachment(c)
        size = a.data_size
        ref = p.IndexRef(pos, c.end - pos, a.name, a.media_type, a.log_time, a.create_time, size)
        index.attachments.append(ref)
    elif opcode == Op.MESSAGE:
        p.parse_message_head(c)
        if written_by_hilrig(index):
            raise p.BadRecordError("a message outside any chunk, which hilrig never writes")
        index.loose_messages.append(pos)
    elif opcode == Op.DATA_END:
        index.data_crc = p.parse_data_end(c)
        index.data_end = pos
    elif opcode == Op.HEADER:
        raise p.BadRecordError("a second header record")
    return None


def add_definitions(index: FileIndex, data: bytes, positions: list[tuple[int, int]]) -> None:
    """Add the Schema and Channel records at ``(opcode, offset)`` of ``data`` (a chunk's
    records) to ``index``, keeping records already known."""
    for opcode, offset in positions:
        try:
            _, c = p.record_at(data, offset, len(data))
            if opcode == Op.SCHEMA:
                schema = p.parse_schema(c)
                index.schemas.setdefault(schema.id, schema)
            else:
                channel = p.parse_channel(c)
                index.channels.setdefault(channel.id, channel)
        except p.BadRecordError:
            continue  # a damaged definition leaves its channel unreadable, reported later


def _truncation(mm: mmap.mmap, pos: int, end: int) -> Truncation:
    opcode = mm[pos] if pos < end else None
    start = stop = None
    head = pos + RECORD_HEADER.size
    if opcode == Op.CHUNK and head + 16 <= end:
        start, stop = (int.from_bytes(mm[head + i : head + i + 8], "little") for i in (0, 8))
    return Truncation(pos, end, opcode, start, stop)


def _check_metadata(index: FileIndex) -> None:
    """The session record's redundant fields must agree; the time window follows from it."""
    record = index.values.get(SESSION_METADATA)
    if record is None:
        return
    try:
        index.session = SessionInfo.checked(record)
    except RecordingError as err:
        index.drop_metadata(SESSION_METADATA, str(err))
        return
    index.window = TimeWindow.of(index.session)


def _check_times(index: FileIndex) -> None:
    """A chunk whose time range the session cannot have is damaged: its range becomes the
    whole window, so that the log times in its (checked) data decide."""
    window = index.window
    for i, chunk in enumerate(index.chunks):
        problem = window.problem(chunk.start_ns, chunk.end_ns)
        if problem is not None:
            index.damaged("chunk record", chunk.offset, problem, chunk.offset + chunk.length)
            index.chunks[i] = replace(chunk, start_ns=window.earliest, end_ns=window.latest)
