"""What a recording holds, for people: session, topics, counts, rates, gaps, loop health, and
whether it is whole.

Counts and timing come from the message indexes (each checked against its chunk's place and
time range), so a whole file is described without decompressing it; the loop's counters come
from its last ``/diagnostics/loop`` message. The data section's CRC, when the file has one, is
checked every time: if it does not match, or with ``check=True``, everything is read
(:mod:`.survey`) to find what is damaged: every chunk and its CRC, every record.
"""

from __future__ import annotations

import mmap
import os
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from hilrig.errors import RecordingError
from hilrig.recording.chunks import (
    ChunkError,
    ChunkIndexError,
    entries_of,
    indexed_entries,
    inflate,
)
from hilrig.recording.file_index import FileIndex
from hilrig.recording.mcap_records import MESSAGE_PREFIX
from hilrig.recording.outcome import OUTCOME_METADATA, SessionOutcome
from hilrig.recording.parse import IndexRef
from hilrig.recording.scan import add_definitions, index_mapped, open_mcap
from hilrig.recording.session import SessionInfo
from hilrig.recording.survey import (
    check_data_crc,
    checked_chunks,
    data_crc_matches,
    loose_messages,
    survey,
)

#: An interval longer than this many median intervals counts as a gap.
GAP_FACTOR = 5.0
LOOP_TOPIC = "/diagnostics/loop"


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
class LoopCounters:
    """The loop's cumulative counters in its last readable ``/diagnostics/loop`` message: its
    tick number, ticks that overran, and rows the recorder's rings refused (recorder drops)."""

    tick: int
    overruns: int
    recorder_drops: int


@dataclass(frozen=True)
class FileInfo:
    """A recording at a glance. ``complete``: its summary is whole and nothing read was damaged
    or missing; ``verified``: every byte was checked (the data section's CRC matched, or all of
    it was read); ``problems`` are one line each (truncation, damage, what it costs)."""

    path: Path
    size: int
    profile: str
    library: str
    complete: bool
    verified: bool
    truncated: bool
    chunks: int
    topics: tuple[TopicInfo, ...]
    metadata: dict[str, dict[str, str]]
    attachments: tuple[IndexRef, ...]
    problems: tuple[str, ...]
    loop: LoopCounters | None = None
    session_problem: str | None = None
    outcome: SessionOutcome | None = None  # the loop's end figures (None: not in the file)
    outcome_problem: str | None = None  # why the outcome record cannot be read

    @property
    def start_ns(self) -> int | None:
        starts = [t.start_ns for t in self.topics if t.start_ns is not None]
        return min(starts) if starts else None

    @property
    def end_ns(self) -> int | None:
        ends = [t.end_ns for t in self.topics if t.end_ns is not None]
        return max(ends) if ends else None

    def session_info(self) -> SessionInfo | None:
        """The session record; None if the file has none. RecordingError if it is damaged."""
        if self.session_problem is not None:
            raise RecordingError(self.session_problem)
        record = self.metadata.get("session")
        return None if record is None else SessionInfo.checked(record)


def inspect(path: str | os.PathLike[str], *, check: bool = False, crc: bool = True) -> FileInfo:
    """Describe ``path``; with ``check``, read and verify all of it; without ``crc``, read only
    its summary, indexes and metadata (the data section's CRC is not checked: ``verified`` is
    False, and damage inside the data section goes unseen until it is read). Raises
    RecordingError (one line) only when it is not an MCAP file at all: damage is reported in
    ``problems``."""
    p, mm = open_mcap(path)
    try:
        index = survey(p, mm) if check else index_mapped(p, mm)
        verified = check or (data_crc_matches(mm, index) if crc else None)
        if verified is False:  # changed somewhere: read all of it to find where
            index, check, verified = survey(p, mm), True, True
        times = _checked_times(mm, index) if check else _indexed_times(mm, index)
        if check:
            check_data_crc(mm, index)
        loop = _loop_counters(p, mm, index, times)
        problems = index.problems()
        try:
            index.session_info()
            session_problem = None
        except RecordingError as err:
            session_problem = str(err)
        outcome, outcome_problem = outcome_of(index)
        return FileInfo(
            path=p,
            size=index.size,
            profile=index.profile,
            library=index.library,
            complete=index.complete and not problems,
            verified=bool(verified),
            truncated=index.truncation is not None,
            chunks=len(index.chunks),
            topics=tuple(_topic_info(index, cid, times.get(cid)) for cid in sorted(index.channels)),
            metadata=index.values,
            attachments=tuple(index.attachments),
            problems=tuple(problems),
            loop=loop,
            session_problem=session_problem,
            outcome=outcome,
            outcome_problem=outcome_problem,
        )
    finally:
        mm.close()


Times = dict[int, npt.NDArray[np.int64]]


def _indexed_times(mm: mmap.mmap, index: FileIndex) -> Times:
    """Log times per channel from the message indexes; a chunk without a usable index is
    decompressed and walked (a damaged index is reported, an unreadable chunk too)."""
    parts: dict[int, list[npt.NDArray[np.int64]]] = defaultdict(list)
    for chunk in index.chunks:
        try:
            entries = indexed_entries(mm, chunk)
        except ChunkIndexError as err:
            index.damaged("message index records of the chunk", chunk.offset, str(err))
            entries = None
        if entries is None:
            try:
                data, _ = inflate(mm, chunk)
                entries, definitions, _ = entries_of(data, None)
            except ChunkError as err:
                end = chunk.offset + chunk.length
                index.damaged("chunk record", chunk.offset, f"unreadable: {err}", end)
                continue
            add_definitions(index, data, definitions)
        for channel_id, (log, _) in entries.items():
            parts[channel_id].append(log)
    for offset in index.loose_messages:
        channel_id, _, log = MESSAGE_PREFIX.unpack_from(mm, offset)[2:5]
        parts[channel_id].append(np.array([log], dtype=np.int64))
    return {cid: np.sort(np.concatenate(p)) for cid, p in parts.items()}


def _checked_times(mm: mmap.mmap, index: FileIndex) -> Times:
    parts: dict[int, list[npt.NDArray[np.int64]]] = defaultdict(list)
    for checked in checked_chunks(mm, index):
        for channel_id, (log, _) in checked.entries.items():
            parts[channel_id].append(log)
    for offset in loose_messages(mm, index):
        channel_id, _, log = MESSAGE_PREFIX.unpack_from(mm, offset)[2:5]
        parts[channel_id].append(np.array([log], dtype=np.int64))
    return {cid: np.sort(np.concatenate(p)) for cid, p in parts.items()}


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


def outcome_of(index: FileIndex) -> tuple[SessionOutcome | None, str | None]:
    """The ``outcome`` record parsed, or why it cannot be (None, None without one)."""
    values = index.values.get(OUTCOME_METADATA)
    if values is None:
        return None, None
    try:
        return SessionOutcome.from_metadata(values), None
    except RecordingError as err:
        return None, str(err)


def _loop_counters(
    path: Path, mm: mmap.mmap, index: FileIndex, times: Times
) -> LoopCounters | None:
    """The counters of the last readable ``/diagnostics/loop`` message, None without one."""
    from hilrig.recording.reader import read_mapped

    ids = [cid for cid, c in index.channels.items() if c.topic == LOOP_TOPIC]
    if not ids or ids[0] not in times or not len(times[ids[0]]):
        return None
    last = int(times[ids[0]][-1])
    frame = read_mapped(path, mm, index, [LOOP_TOPIC], last).frames.get(LOOP_TOPIC)
    needed = {"tick", "overruns", "queue_drops"}
    if frame is None or not len(frame) or not needed <= set(frame.columns):
        return None
    row = frame.iloc[-1]
    return LoopCounters(int(row["tick"]), int(row["overruns"]), int(row["queue_drops"]))
