"""What a recording holds, for people: session, topics, counts, rates, gaps, completeness.

Counts and timing come from the message indexes, so a whole file is described without
decompressing it; ``check=True`` also decompresses every chunk to verify its CRC.
"""

from __future__ import annotations

import mmap
import os
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from hilrig.recording.chunks import ChunkError, indexed_entries, inflate, scan_entries
from hilrig.recording.mcap_records import MESSAGE_PREFIX
from hilrig.recording.scan import (
    AttachmentRef,
    FileIndex,
    add_definitions,
    describe_truncation,
    index_mapped,
    open_mcap,
    read_metadata,
)

#: An interval longer than this many median intervals counts as a gap.
GAP_FACTOR = 5.0


@dataclass(frozen=True)
class TopicInfo:
    """One topic: its type, message count, log-time span (ns), mean rate (Hz), the longest
    interval between messages (ns) and how many intervals exceed GAP_FACTOR x the median."""

    topic: str
    type: str
    count: int
    start_ns: int | None
    end_ns: int | None
    rate_hz: float | None
    max_interval_ns: int | None
    gaps: int


@dataclass(frozen=True)
class FileInfo:
    """A recording at a glance; ``problems`` are one line each (truncation, bad chunks)."""

    path: Path
    size: int
    profile: str
    library: str
    complete: bool
    truncated: bool
    chunks: int
    topics: tuple[TopicInfo, ...]
    metadata: dict[str, dict[str, str]]
    attachments: tuple[AttachmentRef, ...]
    problems: tuple[str, ...]

    @property
    def start_ns(self) -> int | None:
        starts = [t.start_ns for t in self.topics if t.start_ns is not None]
        return min(starts) if starts else None

    @property
    def end_ns(self) -> int | None:
        ends = [t.end_ns for t in self.topics if t.end_ns is not None]
        return max(ends) if ends else None


def inspect(path: str | os.PathLike[str], *, check: bool = False) -> FileInfo:
    """Describe ``path``. Raises RecordingError (one line) if it is not a readable MCAP file."""
    p, mm = open_mcap(path)
    try:
        index = index_mapped(p, mm)
        times, problems = _message_times(mm, index, check=check)
        if index.truncation is not None:
            problems.insert(0, describe_truncation(index))
        elif not index.complete:
            problems.insert(0, f"{p}: summary missing or damaged; indexed by scanning")
        return FileInfo(
            path=p,
            size=index.size,
            profile=index.profile,
            library=index.library,
            complete=index.complete,
            truncated=index.truncation is not None,
            chunks=len(index.chunks),
            topics=tuple(_topic_info(index, cid, times.get(cid)) for cid in sorted(index.channels)),
            metadata=_metadata(mm, index),
            attachments=tuple(index.attachments),
            problems=tuple(problems),
        )
    finally:
        mm.close()


def _message_times(
    mm: mmap.mmap, index: FileIndex, *, check: bool
) -> tuple[dict[int, npt.NDArray[np.int64]], list[str]]:
    parts: dict[int, list[npt.NDArray[np.int64]]] = defaultdict(list)
    problems: list[str] = []
    for chunk in index.chunks:
        entries = None if check else indexed_entries(mm, chunk)
        if entries is None:
            try:
                data = inflate(mm, chunk)
            except ChunkError as err:
                problems.append(f"{index.path}: chunk at byte {chunk.offset} is unreadable: {err}")
                continue
            entries, definitions = scan_entries(data)
            add_definitions(index, data, definitions)
        for channel_id, (log, _) in entries.items():
            parts[channel_id].append(log)
    for offset in index.loose_messages:
        channel_id, _, log = MESSAGE_PREFIX.unpack_from(mm, offset)[2:5]
        parts[channel_id].append(np.array([log], dtype=np.int64))
    return {cid: np.sort(np.concatenate(p)) for cid, p in parts.items()}, problems


def _topic_info(index: FileIndex, channel_id: int, log: npt.NDArray[np.int64] | None) -> TopicInfo:
    channel = index.channels[channel_id]
    schema = index.schemas.get(channel.schema_id)
    kind = schema.name if schema else "(no schema)"
    if log is None or len(log) == 0:
        return TopicInfo(channel.topic, kind, 0, None, None, None, None, 0)
    start, end = int(log[0]), int(log[-1])
    rate = (len(log) - 1) / ((end - start) / 1e9) if end > start else None
    intervals = np.diff(log)
    if len(intervals) == 0:
        return TopicInfo(channel.topic, kind, len(log), start, end, rate, None, 0)
    median = float(np.median(intervals))
    gaps = int((intervals > GAP_FACTOR * median).sum()) if median > 0 else 0
    return TopicInfo(channel.topic, kind, len(log), start, end, rate, int(intervals.max()), gaps)


def _metadata(mm: mmap.mmap, index: FileIndex) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for ref in index.metadata:
        name, values = read_metadata(mm, ref)
        out.setdefault(name, {}).update(values)
    return out
