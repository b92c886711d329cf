"""A file checked through, byte by byte: what ``hilrig info --check`` and ``recover`` read.

:func:`survey` scans the data section record by record (the summary is only compared, never
trusted) and checks the data section's CRC; :func:`checked_chunks` then decompresses every
chunk, checks its CRC, walks or verifies its messages, and compares its header and message
indexes with what it holds. Everything found wrong is added to the index's damage, with what it
costs: a chunk that cannot be read loses its messages (counted per topic when its message index
survived), a wrong time range or message index is rebuilt from the chunk and costs nothing.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

from hilrig.recording.chunks import (
    ChunkError,
    ChunkIndexError,
    Entries,
    entries_of,
    indexed_entries,
    inflate,
)
from hilrig.recording.damage import Damage
from hilrig.recording.definitions import drop_schemaless
from hilrig.recording.file_index import ChunkInfo, FileIndex
from hilrig.recording.mcap_records import RECORD_HEADER
from hilrig.recording.scan import add_definitions, index_mapped
from hilrig.recording.session import utc_iso


def survey(path: Path, mm: mmap.mmap) -> FileIndex:
    """The data section scanned and compared with the summary (channels whose schema is
    missing left out); chunks are read by :func:`checked_chunks`, and :func:`check_data_crc`
    comes last."""
    index = index_mapped(path, mm, use_summary=False)
    drop_schemaless(index)
    return index


@dataclass(frozen=True)
class CheckedChunk:
    """A chunk whose data passed its checks: the decompressed ``data``, its messages per
    channel (known channels only), their log-time span, and whether its header (CRC, times)
    must be written anew."""

    chunk: ChunkInfo
    data: bytes
    entries: Entries
    start_ns: int | None
    end_ns: int | None
    header_damaged: bool
    dropped: bool  # it holds messages of unknown channels, left out of ``entries``


def checked_chunks(mm: mmap.mmap, index: FileIndex) -> Iterator[CheckedChunk]:
    """Every chunk of ``index`` that can be read, checked; the others are added to its damage."""
    for chunk in index.chunks:
        end = chunk.offset + chunk.length
        try:
            data, damaged_field = inflate(mm, chunk)
            hint = _hint(mm, index, replace(chunk, uncompressed_size=len(data)))
            entries, definitions, index_wrong = entries_of(data, hint)
        except ChunkError as err:
            cost = _cost(mm, index, chunk)
            index.damage.append(Damage("chunk record", chunk.offset, str(err), end, cost))
            continue
        add_definitions(index, data, definitions)
        if index_wrong:
            detail = "they do not match the chunk's messages; rebuilt from the chunk"
            index.damaged("message index records of the chunk", chunk.offset, detail)
        if damaged_field:
            detail = (
                f"its {damaged_field} field is damaged; zstd's own checksum vouches for its data"
            )
            index.damaged("chunk record", chunk.offset, detail, end)
        start, stop = _span(entries)
        widened = (chunk.start_ns, chunk.end_ns) == (index.window.earliest, index.window.latest)
        times_wrong = (chunk.start_ns, chunk.end_ns) != (start or 0, stop or 0)
        if times_wrong and not widened:
            detail = (
                f"its time range field ({utc_iso(chunk.start_ns)} to {utc_iso(chunk.end_ns)})"
                " does not match its messages'; theirs are used"
            )
            index.damaged("chunk record", chunk.offset, detail, end)
        known = _known(index, chunk, entries)
        dropped = len(known) < len(entries)
        if dropped:
            start, stop = _span(known)
        header_damaged = times_wrong or bool(damaged_field)
        yield CheckedChunk(chunk, data, known, start, stop, header_damaged, dropped)


def _hint(mm: mmap.mmap, index: FileIndex, chunk: ChunkInfo) -> Entries | None:
    """The chunk's message indexes, None when it has none or one is damaged (reported)."""
    try:
        return indexed_entries(mm, chunk)
    except ChunkIndexError as err:
        index.damaged("message index records of the chunk", chunk.offset, str(err))
        return None


def _span(entries: Entries) -> tuple[int | None, int | None]:
    """The first and last log time of ``entries``; None, None without messages."""
    times = [t for t, _ in entries.values() if len(t)]
    if not times:
        return None, None
    return min(int(t.min()) for t in times), max(int(t.max()) for t in times)


def _known(index: FileIndex, chunk: ChunkInfo, entries: Entries) -> Entries:
    """``entries`` of known channels; messages of others are damage (their channel record is
    damaged or missing), left out."""
    unknown = {cid: len(t) for cid, (t, _) in entries.items() if cid not in index.channels}
    for cid, count in unknown.items():
        detail = f"{count} messages of channel {cid}, whose channel record is damaged or missing"
        index.damage.append(
            Damage("chunk record", chunk.offset, detail, cost=f"those {count} messages are lost")
        )
    return {cid: e for cid, e in entries.items() if cid not in unknown}


def _cost(mm: mmap.mmap, index: FileIndex, chunk: ChunkInfo) -> str:
    """What losing ``chunk`` costs: its time span and, from the message indexes that are
    intact, how many messages of which topic."""
    span = f"from {utc_iso(chunk.start_ns)} to {utc_iso(chunk.end_ns)}"
    counts: dict[str, int] = {}
    complete = chunk.offset not in index.incomplete_indexes
    for cid, offset in sorted(chunk.message_index_offsets.items()):
        try:
            one = replace(chunk, message_index_offsets={cid: offset})
            found = indexed_entries(mm, one)
        except ChunkIndexError:
            complete = False
            continue
        channel = index.channels.get(cid)
        counts[channel.topic if channel else f"channel {cid}"] = len(found[cid][0]) if found else 0
    if not counts:
        return f"its messages {span} are lost (how many is not known)"
    total = sum(counts.values())
    listed = ", ".join(f"{topic} {count}" for topic, count in counts.items())
    how_many = f"{total}" if complete else f"at least {total}"
    return f"its messages {span} are lost: {how_many} ({listed})"


def data_crc_matches(mm: mmap.mmap, index: FileIndex) -> bool | None:
    """Whether the data section's bytes match its CRC; None when the file gives none."""
    if index.data_end is None or not index.data_crc:
        return None
    return zlib.crc32(mm[: index.data_end]) == index.data_crc


def check_data_crc(mm: mmap.mmap, index: FileIndex) -> None:
    """Compare the data section's CRC (when the file gives one) with its bytes; a mismatch is
    reported only when no damaged record in the data section explains it."""
    if index.data_end is None or any(d.offset < index.data_end for d in index.damage):
        return
    if data_crc_matches(mm, index) is False:
        detail = (
            "CRC mismatch, but no damaged record was found: a record without a check of its own"
            " changed (the header, or a metadata record of a file without CRCs of its own)"
        )
        index.damaged("data section", 0, detail, index.data_end)


def loose_messages(mm: mmap.mmap, index: FileIndex) -> list[int]:
    """Offsets of the messages outside chunks whose channel is known; the others are damage."""
    known = []
    for offset in index.loose_messages:
        channel_id = struct.unpack_from("<H", mm, offset + RECORD_HEADER.size)[0]
        if channel_id in index.channels:
            known.append(offset)
        else:
            detail = f"its channel {channel_id} has no (intact) channel record"
            index.damage.append(Damage("message record", offset, detail, cost="it is lost"))
    return known
