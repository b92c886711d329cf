"""Load recordings into pandas: one frame per topic, one column per field, at memory speed.

Fixed-layout channels (every hilrig stream) go through :mod:`.columns` - numpy views over the
decompressed chunks; any other ROS 2 channel is decoded by ``mcap_ros2`` (:mod:`.generic`).
Topic and time-range selection use the summary's chunk and message indexes, so unselected
chunks are never decompressed. A truncated or unfinished file loads every complete chunk and
says what was lost; a corrupt chunk is skipped and reported.
"""

from __future__ import annotations

import mmap
import os
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd

from hilrig.errors import RecordingError
from hilrig.recording.cdr import LayoutError, layout_of
from hilrig.recording.chunks import ChunkError, Entries, indexed_entries, inflated, scan_entries
from hilrig.recording.columns import INDEX_NAME, FixedChannel, Rows
from hilrig.recording.generic import DecodeError, RawMessage, decode_frame
from hilrig.recording.mcap_records import MESSAGE_PREFIX, RECORD_HEADER, Channel, Schema
from hilrig.recording.msgdef import parse_schema, short_name
from hilrig.recording.scan import ChunkInfo, FileIndex, add_definitions, index_mapped, open_mcap
from hilrig.recording.schema import MESSAGE_ENCODING, SCHEMA_ENCODING
from hilrig.recording.session import utc_iso

PathLike = str | os.PathLike[str]
Progress = Callable[[int, int], None]


class RecordingWarning(UserWarning):
    """Data was lost or skipped while loading (truncated file, corrupt chunk, foreign channel)."""


@dataclass(frozen=True)
class Loaded:
    """What :func:`read` returns: the frames, and one line per problem met while loading."""

    frames: dict[str, pd.DataFrame]
    problems: tuple[str, ...]
    index: FileIndex


def load(
    path: PathLike | Sequence[PathLike],
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> dict[str, pd.DataFrame]:
    """Load a recording (or the numbered files of a split session, in order) into pandas.

    Returns one DataFrame per topic, indexed by MCAP log time (int64 ns since the Unix epoch,
    index name ``log_time_ns``), with ``publish_time_ns`` and ``sequence`` from the records,
    then one column per message field: dotted paths (``wrench.force.x``), ``_i`` per array
    element (``position_0``), ``<path>_ns`` for times (``header.stamp_ns``), strings as
    categoricals. ``topics`` selects topics; ``start_ns <= log time < end_ns`` selects time.
    Every problem met (truncation, corrupt chunk) is reported as a RecordingWarning.
    Raises RecordingError (one line naming the file) for unreadable input or unknown topics.
    """
    paths = [path] if isinstance(path, (str, os.PathLike)) else list(path)
    parts = [read(p, topics, start_ns, end_ns) for p in paths]
    for part in parts:
        for problem in part.problems:
            warnings.warn(problem, RecordingWarning, stacklevel=2)
    if len(parts) == 1:
        return parts[0].frames
    topics_seen = dict.fromkeys(t for part in parts for t in part.frames)
    return {
        t: pd.concat([p.frames[t] for p in parts if t in p.frames]).sort_index(kind="stable")
        for t in topics_seen
    }


def read(
    path: PathLike,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
    *,
    progress: Progress | None = None,
) -> Loaded:
    """:func:`load` for one file, returning the problems instead of warning about them.

    ``progress(done, total)`` is called after each chunk read (a count of chunks).
    """
    p, mm = open_mcap(path)
    try:
        index = index_mapped(p, mm)
        return _Load(mm, index, topics, start_ns, end_ns, progress).run()
    finally:
        mm.close()


class _Accumulator:
    """The messages of one channel, gathered as fixed-layout rows or, failing that, raw."""

    def __init__(self, path: Path, channel: Channel, schema: Schema | None) -> None:
        self.path, self.channel, self.schema = path, channel, schema
        self.fixed: FixedChannel | None = None
        self.rows: list[Rows] = []
        self.raw: list[RawMessage] | None = None

    def add(self, data: bytes, offsets: npt.NDArray[np.int64]) -> None:
        if self.raw is None:
            if self.fixed is None:
                self.fixed = self._fixed_layout(data, int(offsets[0]))
            rows = self.fixed.gather(data, offsets) if self.fixed else None
            if rows is not None:
                self.rows.append(rows)
                return
            self.raw = [m for rows in self.rows for m in _rows_to_raw(rows)]
            self.rows = []
        self.raw.extend(_raw_messages(data, offsets))

    def _fixed_layout(self, data: bytes, offset: int) -> FixedChannel | None:
        if self.schema is None:
            return None
        _, length = RECORD_HEADER.unpack_from(data, offset)
        message = data[offset + MESSAGE_PREFIX.size : offset + RECORD_HEADER.size + length]
        try:
            defs = parse_schema(self.schema.name, self.schema.data.decode())
            return FixedChannel(
                self.channel.id, layout_of(defs, short_name(self.schema.name), message)
            )
        except (LayoutError, RecordingError, UnicodeDecodeError):
            return None

    def frame(self) -> pd.DataFrame:
        if self.raw is None and self.fixed is not None:
            rows = np.concatenate(self.rows) if len(self.rows) != 1 else self.rows[0]
            if self.fixed.consistent(rows):
                return self.fixed.frame(rows)
            self.raw = _rows_to_raw(rows)
        if not self.raw:
            columns = {"publish_time_ns": np.empty(0, np.int64), "sequence": np.empty(0, np.uint32)}
            return pd.DataFrame(columns, index=pd.Index(np.empty(0, np.int64), name=INDEX_NAME))
        assert self.schema is not None  # channels without a schema are refused up front
        try:
            return decode_frame(self.schema, self.raw)
        except DecodeError as err:
            raise RecordingError(f"{self.path}: topic {self.channel.topic}: {err}") from err


def _raw_messages(data: bytes, offsets: npt.NDArray[np.int64]) -> list[RawMessage]:
    out: list[RawMessage] = []
    for offset in offsets.tolist():
        _, length, _, sequence, log, publish = MESSAGE_PREFIX.unpack_from(data, offset)
        end = offset + RECORD_HEADER.size + length
        out.append((log, publish, sequence, data[offset + MESSAGE_PREFIX.size : end]))
    return out


def _rows_to_raw(rows: Rows) -> list[RawMessage]:
    out: list[RawMessage] = []
    for row in rows:
        record = row.tobytes()
        _, _, _, sequence, log, publish = MESSAGE_PREFIX.unpack_from(record)
        out.append((log, publish, sequence, record[MESSAGE_PREFIX.size :]))
    return out


class _Load:
    """One file's load: choose chunks, inflate them, route messages to accumulators."""

    def __init__(
        self,
        mm: mmap.mmap,
        index: FileIndex,
        topics: Iterable[str] | None,
        start_ns: int | None,
        end_ns: int | None,
        progress: Progress | None,
    ) -> None:
        self.mm, self.index, self.progress = mm, index, progress
        self.topics = None if topics is None else set(topics)
        self.start = 0 if start_ns is None else start_ns
        self.end = 2**64 if end_ns is None else end_ns
        self.problems: list[str] = []
        self.accumulators: dict[int, _Accumulator] = {}
        self.refused: set[int] = set()

    def run(self) -> Loaded:
        path = self.index.path
        chunks = self._chunks()
        for done, (chunk, data) in enumerate(inflated(self.mm, chunks), start=1):
            if self.progress is not None:
                self.progress(done, len(chunks))
            if isinstance(data, ChunkError):
                span = f"{utc_iso(chunk.start_ns)} to {utc_iso(chunk.end_ns)}"
                self.problems.append(
                    f"{path}: chunk at byte {chunk.offset} ({span}) skipped: {data}"
                )
                continue
            self._route(chunk, data)
        self._loose_messages()
        self._check_topics()
        if self.index.truncation is not None:
            self.problems.insert(0, describe_truncation(self.index))
        elif not self.index.complete:
            self.problems.insert(
                0, f"{self.index.path}: summary missing or damaged; read by scanning every record"
            )
        frames = {a.channel.topic: a.frame() for a in self.accumulators.values()}
        return Loaded(dict(sorted(frames.items())), tuple(self.problems), self.index)

    def _chunks(self) -> list[ChunkInfo]:
        """The chunks that may hold selected messages; a chunk whose channels are not all
        known yet (their records are inside chunks) is always read."""
        wanted = {cid for cid, ch in self.index.channels.items() if self._selected(ch)}
        known = set(self.index.channels)
        return [
            c
            for c in self.index.chunks
            if c.end_ns >= self.start
            and c.start_ns < self.end
            and (
                not c.message_index_offsets
                or not wanted.isdisjoint(c.message_index_offsets)
                or not known.issuperset(c.message_index_offsets)
            )
        ]

    def _selected(self, channel: Channel) -> bool:
        return self.topics is None or channel.topic in self.topics

    def _route(self, chunk: ChunkInfo, data: bytes) -> None:
        entries: Entries | None = indexed_entries(self.mm, chunk)
        if entries is None or not set(entries) <= set(self.index.channels):
            entries, definitions = scan_entries(data)
            add_definitions(self.index, data, definitions)
        for channel_id, (times, offsets) in entries.items():
            accumulator = self._accumulator(channel_id)
            if accumulator is None:
                continue
            keep = (times >= self.start) & (times < self.end)
            if not keep.all():
                offsets = offsets[keep]
            if len(offsets):
                accumulator.add(data, offsets)

    def _accumulator(self, channel_id: int) -> _Accumulator | None:
        accumulator = self.accumulators.get(channel_id)
        if accumulator is not None or channel_id in self.refused:
            return accumulator
        channel = self.index.channels.get(channel_id)
        if channel is None or not self._selected(channel):
            return None
        schema = self.index.schemas.get(channel.schema_id)
        if schema is None or schema.encoding != SCHEMA_ENCODING:
            problem = f"schema encoding {schema.encoding!r}" if schema else "no schema"
        elif channel.message_encoding != MESSAGE_ENCODING:
            problem = f"message encoding {channel.message_encoding!r}"
        else:
            accumulator = self.accumulators[channel_id] = _Accumulator(
                self.index.path, channel, schema
            )
            return accumulator
        line = f"{self.index.path}: topic {channel.topic} has {problem}, not ros2msg/cdr"
        if self.topics is not None:
            raise RecordingError(line)
        self.problems.append(line + "; skipped")
        self.refused.add(channel_id)
        return None

    def _loose_messages(self) -> None:
        for offset in self.index.loose_messages:
            _, length = RECORD_HEADER.unpack_from(self.mm, offset)
            record = self.mm[offset : offset + RECORD_HEADER.size + length]
            channel_id, _, log, _ = MESSAGE_PREFIX.unpack_from(record)[2:6]
            accumulator = self._accumulator(channel_id)
            if accumulator is not None and self.start <= log < self.end:
                accumulator.add(record, np.zeros(1, dtype=np.int64))

    def _check_topics(self) -> None:
        known = {c.topic for c in self.index.channels.values()}
        missing = sorted((self.topics or set()) - known)
        if missing:
            have = ", ".join(sorted(known))
            raise RecordingError(f"{self.index.path}: no topic {', '.join(missing)} (has {have})")
        for cid, channel in self.index.channels.items():
            if self._selected(channel) and cid not in self.refused:
                self._accumulator(cid)


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
