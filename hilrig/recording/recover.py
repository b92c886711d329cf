"""Make a truncated, unfinished or damaged MCAP file whole again, and say exactly what was lost.

The source is checked through (:mod:`.survey`): its data section scanned record by record (the
summary only compared), damaged records skipped. Every intact record is kept: schemas, channels
(the summary's copy where the data section's is damaged), metadata and attachments as they
are, and every chunk whose data passes its checks with its compressed bytes as they are - its
header written anew when its CRC or time range field was damaged, its message indexes rebuilt
from its contents. A fresh summary (statistics, chunk, metadata and attachment indexes) and a
footer follow, and the data section's CRC, so every MCAP tool opens the result. The output is
written through :func:`hilrig.outputs.new_files`: all of it, or nothing.
"""

from __future__ import annotations

import mmap
import os
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
import zstandard

from hilrig.outputs import new_files
from hilrig.recording import mcap_records as rec
from hilrig.recording.chunks import Entries
from hilrig.recording.file_index import FileIndex, Truncation
from hilrig.recording.scan import open_mcap
from hilrig.recording.session import utc_iso
from hilrig.recording.survey import (
    CheckedChunk,
    check_data_crc,
    checked_chunks,
    data_crc_matches,
    loose_messages,
    survey,
)

_COMPRESSOR = zstandard.ZstdCompressor(level=3, write_checksum=True)


@dataclass(frozen=True)
class Recovery:
    """What :func:`recover` kept and lost; times are MCAP log times (int64 ns).
    ``was_complete``: the source was whole and nothing in it was found damaged (``verified``:
    its data section's CRC vouched for every byte of it); ``problems``: one
    line per damaged or missing part (which record, its bytes, what it cost); ``lost``:
    messages lost per topic, where the source's summary or message indexes tell."""

    source: Path
    output: Path
    messages: int
    chunks: int
    start_ns: int | None
    end_ns: int | None
    was_complete: bool
    verified: bool
    truncation: Truncation | None
    problems: tuple[str, ...]
    lost: dict[str, int]

    def summary(self) -> str:
        """A few lines for people: messages kept, what was damaged and what it cost."""
        span = (
            f"from {utc_iso(self.start_ns)} to {utc_iso(self.end_ns)}"
            if self.start_ns is not None and self.end_ns is not None
            else "(no messages)"
        )
        lines = [f"kept {self.messages} messages in {self.chunks} chunks, {span}"]
        if self.was_complete and self.verified:
            lines.append("the source was whole and undamaged; nothing was lost")
        elif self.was_complete:
            lines.append(
                "no damage was found; without a data section CRC in the source, a changed value"
                " in a record with no check of its own would go unseen"
            )
        lines.extend(self.problems)
        if self.lost:
            counts = ", ".join(f"{topic} {count}" for topic, count in sorted(self.lost.items()))
            lines.append(f"messages lost per topic: {counts}")
        return "\n".join(lines)


def recover(source: str | os.PathLike[str], output: str | os.PathLike[str]) -> Recovery:
    """Write a valid copy of ``source`` to ``output`` with every intact record.

    Raises RecordingError if ``source`` is not MCAP, OutputError if ``output`` exists or
    cannot be written (nothing is left behind).
    """
    path, mm = open_mcap(source)
    try:
        with new_files(Path(output)) as (temporary,), temporary.open("xb") as out:
            return _Rewriter(mm, survey(path, mm), out, Path(output)).run()
    finally:
        mm.close()


class _Rewriter:
    def __init__(self, mm: mmap.mmap, index: FileIndex, out: BinaryIO, output: Path) -> None:
        self.mm, self.index, self.out, self.output = mm, index, out, output
        self.pos = 0
        self.crc = 0
        self.counts: Counter[int] = Counter()
        self.start, self.end = 2**64, -1
        self.chunk_indexes: list[rec.ChunkIndex] = []
        self.metadata_indexes: list[bytes] = []
        self.attachment_indexes: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.out.write(data)
        self.pos += len(data)
        self.crc = zlib.crc32(data, self.crc)

    def run(self) -> Recovery:
        index = self.index
        self.write(rec.MAGIC + rec.header(index.profile, index.library))
        for schema in index.schemas.values():
            self.write(schema.encode())
        for channel in index.channels.values():
            self.write(channel.encode())
        self._copy_metadata_and_attachments()
        for checked in checked_chunks(self.mm, index):
            self._copy_chunk(checked)
        for offset in loose_messages(self.mm, index):
            self._copy_loose_message(offset)
        check_data_crc(self.mm, index)
        self._finish()
        problems = index.problems()
        return Recovery(
            source=index.path,
            output=self.output,
            messages=sum(self.counts.values()),
            chunks=len(self.chunk_indexes),
            start_ns=self.start if self.counts else None,
            end_ns=self.end if self.counts else None,
            was_complete=index.complete and not problems,
            verified=data_crc_matches(self.mm, index) is True,
            truncation=index.truncation,
            problems=tuple(problems),
            lost=self._lost(),
        )

    def _finish(self) -> None:
        index = self.index
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
        self.out.write(
            rec.data_end_and_summary(
                self.pos,
                schemas=list(index.schemas.values()),
                channels=list(index.channels.values()),
                statistics=statistics,
                chunk_indexes=self.chunk_indexes,
                attachment_indexes=self.attachment_indexes,
                metadata_indexes=self.metadata_indexes,
                data_crc=self.crc,
            )
        )

    def _lost(self) -> dict[str, int]:
        """Messages lost per topic, from the source summary's statistics when it is whole."""
        stats = self.index.statistics
        if stats is None:
            return {}
        lost = {}
        for cid, count in stats.channel_message_counts.items():
            channel = self.index.channels.get(cid)
            missing = count - self.counts[cid]
            if missing > 0:
                lost[channel.topic if channel else f"channel {cid}"] = missing
        return lost

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

    def _copy_chunk(self, checked: CheckedChunk) -> None:
        chunk, entries, data = checked.chunk, checked.entries, checked.data
        start, end = checked.start_ns or 0, checked.end_ns or 0
        offset = self.pos
        compression = chunk.compression
        raw = self.mm[chunk.data_offset : chunk.data_offset + chunk.compressed_size]
        if checked.dropped:  # its data holds messages of unknown channels: packed without them
            data, entries = _kept_records(data, entries)
            compression, raw = "zstd", _COMPRESSOR.compress(data)
        if checked.header_damaged or checked.dropped:
            head = rec.chunk_head(
                start_ns=start,
                end_ns=end,
                uncompressed_size=len(data),
                uncompressed_crc=zlib.crc32(data),
                compression=compression,
                compressed_size=len(raw),
            )
            self.write(head + raw)
        else:
            self.write(self.mm[chunk.offset : chunk.offset + chunk.length])
        length = self.pos - offset
        index_start = self.pos
        index_offsets: dict[int, int] = {}
        for channel_id, (times, positions) in entries.items():
            index_offsets[channel_id] = self.pos
            pairs = np.column_stack([times, positions]).astype("<u8").tobytes()
            self.write(rec.message_index(channel_id, pairs))
            self.counts[channel_id] += len(times)
        if checked.start_ns is not None and checked.end_ns is not None:
            self.start, self.end = min(self.start, start), max(self.end, end)
        self.chunk_indexes.append(
            rec.ChunkIndex(
                start,
                end,
                offset,
                length,
                index_offsets,
                self.pos - index_start,
                compression,
                len(raw),
                len(data),
            )
        )

    def _copy_loose_message(self, offset: int) -> None:
        _, length = rec.RECORD_HEADER.unpack_from(self.mm, offset)
        record = self.mm[offset : offset + rec.RECORD_HEADER.size + length]
        channel_id, _, log, _ = rec.MESSAGE_PREFIX.unpack_from(record)[2:6]
        self.write(record)
        self.counts[channel_id] += 1
        self.start, self.end = min(self.start, log), max(self.end, log)


def _kept_records(data: bytes, entries: Entries) -> tuple[bytes, Entries]:
    """The records of ``entries`` (a chunk's data, some messages left out), back to back in
    their order, and where each now is."""
    records = sorted(
        (offset, channel_id, log)
        for channel_id, (times, offsets) in entries.items()
        for log, offset in zip(times.tolist(), offsets.tolist(), strict=True)
    )
    out = bytearray()
    kept: dict[int, tuple[list[int], list[int]]] = {}
    for offset, channel_id, log in records:
        _, length = rec.RECORD_HEADER.unpack_from(data, offset)
        times, offsets = kept.setdefault(channel_id, ([], []))
        times.append(log)
        offsets.append(len(out))
        out += data[offset : offset + rec.RECORD_HEADER.size + length]
    return bytes(out), {
        cid: (np.array(t, dtype=np.int64), np.array(o, dtype=np.int64))
        for cid, (t, o) in kept.items()
    }
