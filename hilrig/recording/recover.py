"""Make a truncated, unfinished or partly corrupt MCAP file whole again.

The data section is scanned record by record (the summary, if any, is not trusted). Every
complete record is kept: schemas, channels, metadata and attachments as they are, every chunk
whose data passes its CRC verbatim (no recompression) with its message indexes rebuilt from
its contents. A fresh summary - statistics, chunk, metadata and attachment indexes - and the
footer follow, so every MCAP tool opens the result.
"""

from __future__ import annotations

import mmap
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from hilrig.errors import RecordingError
from hilrig.recording import mcap_records as rec
from hilrig.recording.chunks import ChunkError, Entries, indexed_entries, inflate, scan_entries
from hilrig.recording.scan import (
    ChunkInfo,
    FileIndex,
    Truncation,
    add_definitions,
    describe_truncation,
    index_mapped,
    open_mcap,
)
from hilrig.recording.session import utc_iso


@dataclass(frozen=True)
class Recovery:
    """What :func:`recover` kept and lost; times are MCAP log times (int64 ns)."""

    source: Path
    output: Path
    messages: int
    chunks: int
    start_ns: int | None
    end_ns: int | None
    was_complete: bool
    truncation: Truncation | None
    problems: tuple[str, ...]

    def summary(self) -> str:
        """A few lines for people: messages kept, the time span lost, chunks dropped."""
        span = (
            f"from {utc_iso(self.start_ns)} to {utc_iso(self.end_ns)}"
            if self.start_ns is not None and self.end_ns is not None
            else "(no messages)"
        )
        lines = [f"kept {self.messages} messages in {self.chunks} chunks, {span}"]
        if self.was_complete:
            lines.append("the source was already complete; it was rewritten unchanged in content")
        lines.extend(self.problems)
        return "\n".join(lines)


def recover(source: str | os.PathLike[str], output: str | os.PathLike[str]) -> Recovery:
    """Write a valid copy of ``source`` to ``output`` with every complete, intact record.

    Raises RecordingError if ``source`` is not MCAP, or ``output`` exists or is the source.
    """
    src, dst = Path(source), Path(output)
    if dst.exists():
        raise RecordingError(f"{dst}: already exists; refusing to overwrite it")
    path, mm = open_mcap(src)
    try:
        complete = index_mapped(path, mm).complete
        index = index_mapped(path, mm, use_summary=False)
        try:
            with dst.open("xb") as out:
                return _Rewriter(mm, index, out, dst, was_complete=complete).run()
        except BaseException:
            dst.unlink(missing_ok=True)
            raise
    finally:
        mm.close()


class _Rewriter:
    def __init__(
        self,
        mm: mmap.mmap,
        index: FileIndex,
        out: BinaryIO,
        output: Path,
        *,
        was_complete: bool,
    ) -> None:
        self.mm, self.index, self.output, self.was_complete = mm, index, output, was_complete
        self.out = out
        self.pos = 0
        self.counts: Counter[int] = Counter()
        self.start, self.end = 2**64, -1
        self.chunk_indexes: list[rec.ChunkIndex] = []
        self.metadata_indexes: list[bytes] = []
        self.attachment_indexes: list[bytes] = []
        self.problems: list[str] = []

    def write(self, data: bytes) -> None:
        self.out.write(data)
        self.pos += len(data)

    def run(self) -> Recovery:
        index = self.index
        self.write(rec.MAGIC + rec.header(index.profile, index.library))
        for schema in index.schemas.values():
            self.write(schema.encode())
        for channel in index.channels.values():
            self.write(channel.encode())
        self._copy_metadata_and_attachments()
        for chunk in index.chunks:
            try:
                data = inflate(self.mm, chunk)
            except ChunkError as err:
                span = f"{utc_iso(chunk.start_ns)} to {utc_iso(chunk.end_ns)}"
                self.problems.append(f"dropped the chunk at byte {chunk.offset} ({span}): {err}")
                continue
            self._copy_chunk(chunk, data)
        self._copy_loose_messages()
        if index.truncation is not None:
            self.problems.append(describe_truncation(index))
        statistics = rec.Statistics(
            message_count=sum(self.counts.values()),
            schema_count=len(index.schemas),
            channel_count=len(index.channels),
            attachment_count=len(self.attachment_indexes),
            metadata_count=len(self.metadata_indexes),
            chunk_count=len(self.chunk_indexes),
            message_start_time=self.start if self.counts else 0,
            message_end_time=self.end if self.counts else 0,
            channel_message_counts={cid: self.counts[cid] for cid in index.channels},
        )
        self.write(
            rec.data_end_and_summary(
                self.pos,
                schemas=list(index.schemas.values()),
                channels=list(index.channels.values()),
                statistics=statistics,
                chunk_indexes=self.chunk_indexes,
                attachment_indexes=self.attachment_indexes,
                metadata_indexes=self.metadata_indexes,
            )
        )
        has_messages = bool(self.counts)
        return Recovery(
            source=index.path,
            output=self.output,
            messages=sum(self.counts.values()),
            chunks=len(self.chunk_indexes),
            start_ns=self.start if has_messages else None,
            end_ns=self.end if has_messages else None,
            was_complete=self.was_complete,
            truncation=index.truncation,
            problems=tuple(self.problems),
        )

    def _copy_metadata_and_attachments(self) -> None:
        for ref in self.index.metadata:
            offset = self.pos
            self.write(self.mm[ref.offset : ref.offset + ref.length])
            self.metadata_indexes.append(rec.metadata_index(offset, ref.length, ref.name))
        for att in self.index.attachments:
            offset = self.pos
            self.write(self.mm[att.offset : att.offset + att.length])
            self.attachment_indexes.append(
                rec.attachment_index(
                    offset,
                    att.length,
                    name=att.name,
                    media_type=att.media_type,
                    log_time=att.log_time,
                    create_time=att.create_time,
                    data_size=att.data_size,
                )
            )

    def _copy_chunk(self, chunk: ChunkInfo, data: bytes) -> None:
        entries: Entries | None = indexed_entries(self.mm, chunk)
        if entries is None:
            entries, definitions = scan_entries(data)
            add_definitions(self.index, data, definitions)
        offset = self.pos
        self.write(self.mm[chunk.offset : chunk.offset + chunk.length])
        index_start = self.pos
        index_offsets: dict[int, int] = {}
        for channel_id, (times, positions) in entries.items():
            index_offsets[channel_id] = self.pos
            pairs = np.column_stack([times, positions]).astype("<u8").tobytes()
            self.write(rec.message_index(channel_id, pairs))
            self.counts[channel_id] += len(times)
            if len(times):
                self.start, self.end = (
                    min(self.start, int(times.min())),
                    max(self.end, int(times.max())),
                )
        self.chunk_indexes.append(
            rec.ChunkIndex(
                chunk.start_ns,
                chunk.end_ns,
                offset,
                chunk.length,
                index_offsets,
                self.pos - index_start,
                chunk.compression,
                chunk.compressed_size,
                chunk.uncompressed_size,
            )
        )

    def _copy_loose_messages(self) -> None:
        for offset in self.index.loose_messages:
            _, length = rec.RECORD_HEADER.unpack_from(self.mm, offset)
            record = self.mm[offset : offset + rec.RECORD_HEADER.size + length]
            channel_id, _, log, _ = rec.MESSAGE_PREFIX.unpack_from(record)[2:6]
            self.write(record)
            self.counts[channel_id] += 1
            self.start, self.end = min(self.start, log), max(self.end, log)
