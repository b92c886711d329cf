"""The summary section: read when its CRC matches, and every record it points to checked
against it."""

from __future__ import annotations

import mmap
import zlib
from typing import TypeVar

from hilrig.recording import parse as p
from hilrig.recording.file_index import ChunkInfo, FileIndex
from hilrig.recording.mcap_records import (
    MAGIC,
    RECORD_HEADER,
    Channel,
    ChunkIndex,
    Op,
    Schema,
    Statistics,
)

_FOOTER_SIZE = RECORD_HEADER.size + 20
_DATA_END_SIZE = RECORD_HEADER.size + 4
T = TypeVar("T")


class Summary:
    """A summary section whose CRC matched, parsed (schemas, channels, indexes)."""

    def __init__(self, start: int) -> None:
        self.start = start
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.chunks: list[ChunkIndex] = []
        self.metadata: list[p.IndexRef] = []
        self.attachments: list[p.IndexRef] = []
        self.statistics: Statistics | None = None

    @classmethod
    def read(cls, mm: mmap.mmap, index: FileIndex) -> Summary | None:
        """The summary, or None when there is none (an unfinished file) or it is damaged."""
        size = len(mm)
        footer_at = size - len(MAGIC) - _FOOTER_SIZE
        if footer_at < len(MAGIC) or mm[size - len(MAGIC) :] != MAGIC:
            return None
        try:
            opcode, c = p.record_at(mm, footer_at, size - len(MAGIC))
            if opcode != Op.FOOTER:
                raise p.BadRecordError(f"it is a {p.kind(opcode)}")
            start, offsets_start, crc = p.parse_footer(c)
            data_end = (start or footer_at) - _DATA_END_SIZE
            if start and not (len(MAGIC) < data_end and start <= footer_at):
                raise p.BadRecordError(f"its summary start ({start}) is outside the file")
            if offsets_start and not start <= offsets_start <= footer_at:
                raise p.BadRecordError(f"its summary offsets start ({offsets_start}) is outside")
        except p.BadRecordError as err:
            index.damaged("footer record", footer_at, str(err), size)
            return None
        _data_end(mm, index, data_end)
        if not start:
            return None
        if crc and zlib.crc32(mm[start : footer_at + _FOOTER_SIZE - 4]) != crc:
            index.damaged("summary section", start, "CRC mismatch", footer_at)
            return None
        summary = cls(start)
        try:
            summary._parse(mm, start, footer_at)
        except p.BadRecordError as err:
            index.damaged("summary section", start, str(err), footer_at)
            return None
        return summary

    def _parse(self, mm: mmap.mmap, pos: int, end: int) -> None:
        while pos < end:
            opcode, c = p.record_at(mm, pos, end)
            if opcode == Op.SCHEMA:
                schema = p.parse_schema(c)
                self.schemas[schema.id] = schema
            elif opcode == Op.CHANNEL:
                channel = p.parse_channel(c)
                self.channels[channel.id] = channel
            elif opcode == Op.CHUNK_INDEX:
                self.chunks.append(p.parse_chunk_index(c))
            elif opcode == Op.METADATA_INDEX:
                self.metadata.append(p.parse_metadata_index(c))
            elif opcode == Op.ATTACHMENT_INDEX:
                self.attachments.append(p.parse_attachment_index(c))
            elif opcode == Op.STATISTICS:
                self.statistics = p.parse_statistics(c)
            elif opcode == Op.SUMMARY_OFFSET:
                p.parse_summary_offset(c)
            else:
                raise p.BadRecordError(f"it holds a {p.kind(opcode)} at byte {pos}")
            pos = c.end
        if self.chunks and not self.channels:
            raise p.BadRecordError("it indexes chunks but lists no channels")

    def fill(self, mm: mmap.mmap, index: FileIndex) -> None:
        """``index`` from this summary, each record it points to checked against it."""
        index.schemas, index.channels = dict(self.schemas), dict(self.channels)
        limit = index.data_end if index.data_end is not None else self.start
        for entry in sorted(self.chunks, key=lambda ch: ch.chunk_start_offset):
            index.chunks.append(_indexed_chunk(mm, index, entry, limit))
        for ref in self.metadata:
            try:
                opcode, c = p.record_at(mm, ref.offset, min(limit, ref.offset + ref.length))
                name, values = p.parse_metadata(c) if opcode == Op.METADATA else ("", {})
                if opcode != Op.METADATA or name != ref.name or c.end != ref.offset + ref.length:
                    raise p.BadRecordError("it does not match its index in the summary")
            except p.BadRecordError as err:
                end = ref.offset + ref.length
                index.damaged(f"metadata record {ref.name!r}", ref.offset, str(err), end)
                continue
            index.metadata.append(ref)
            index.values.setdefault(name, {}).update(values)
        for ref in self.attachments:
            try:
                opcode, c = p.record_at(mm, ref.offset, min(limit, ref.offset + ref.length))
                head = p.parse_attachment(c) if opcode == Op.ATTACHMENT else None
                if head is None or (head.name, head.data_size) != (ref.name, ref.data_size):
                    raise p.BadRecordError("it does not match its index in the summary")
            except p.BadRecordError as err:
                end = ref.offset + ref.length
                index.damaged(f"attachment record {ref.name!r}", ref.offset, str(err), end)
                continue
            index.attachments.append(ref)

    def compare_metadata(self, index: FileIndex) -> None:
        """After a scan: a metadata record the summary lists but the scan did not find intact
        where it says is damaged."""
        found = {(ref.offset, ref.name) for ref in index.metadata}
        reported = {d.offset for d in index.damage}
        for ref in self.metadata:
            if (ref.offset, ref.name) not in found and ref.offset not in reported:
                detail = "it is missing or damaged where the summary lists it"
                end = ref.offset + ref.length
                index.damaged(f"metadata record {ref.name!r}", ref.offset, detail, end)

    def compare_definitions(self, index: FileIndex) -> None:
        """After a scan: schemas and channels of the data section that differ from the
        summary's copies are damaged; the summary's are taken."""
        _replace_damaged(index, "schema", Op.SCHEMA, index.schemas, self.schemas)
        _replace_damaged(index, "channel", Op.CHANNEL, index.channels, self.channels)


def _replace_damaged(
    index: FileIndex, kind: str, opcode: Op, found: dict[int, T], copies: dict[int, T]
) -> None:
    for key, copy in copies.items():
        if found.get(key) != copy:
            if key in found:
                offset = index.definition_offsets.get((opcode, key), 0)
                detail = "it differs from its copy in the summary, which was used"
                index.damaged(f"{kind} record {key}", offset, detail)
            found[key] = copy


def _data_end(mm: mmap.mmap, index: FileIndex, at: int) -> None:
    try:
        opcode, c = p.record_at(mm, at, at + _DATA_END_SIZE)
        if opcode != Op.DATA_END:
            raise p.BadRecordError(f"a {p.kind(opcode)} is where the summary says it is")
        index.data_crc = p.parse_data_end(c)
        index.data_end = at
    except p.BadRecordError as err:
        index.damaged("data end record", at, str(err), at + _DATA_END_SIZE)


def _indexed_chunk(mm: mmap.mmap, index: FileIndex, entry: ChunkIndex, limit: int) -> ChunkInfo:
    """A chunk as its (CRC-checked) index gives it; its record's header is compared."""
    offset, length = entry.chunk_start_offset, entry.chunk_length
    crc: int | None = None
    try:
        if offset + length > limit:
            raise p.BadRecordError("its index puts it past the data section")
        opcode, c = p.record_at(mm, offset, offset + length)
        head = p.parse_chunk(c) if opcode == Op.CHUNK else None
        if head is None or c.end != offset + length:
            raise p.BadRecordError("it does not match its index in the summary")
        given = (head.start_ns, head.end_ns, head.compression, head.compressed_size)
        indexed = (entry.message_start_time, entry.message_end_time, entry.compression)
        if given != (*indexed, entry.compressed_size) or (
            head.uncompressed_size != entry.uncompressed_size
        ):
            raise p.BadRecordError("its header does not match its index in the summary")
        crc = head.uncompressed_crc
    except p.BadRecordError as err:
        detail = f"its header is damaged ({err}); its index in the summary is used instead"
        index.damaged("chunk record", offset, detail, offset + length)
    return ChunkInfo(
        offset,
        length,
        entry.message_start_time,
        entry.message_end_time,
        entry.compression,
        offset + length - entry.compressed_size,
        entry.compressed_size,
        entry.uncompressed_size,
        crc,
        dict(entry.message_index_offsets),
    )
