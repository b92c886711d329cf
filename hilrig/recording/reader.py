"""Load recordings into pandas: one frame per topic, one column per field, at memory speed.

Fixed-layout channels (every hilrig stream) go through :mod:`.columns` - numpy views over
batches of decompressed chunks; any other ROS 2 channel is decoded message by message by
``mcap_ros2`` (:mod:`.generic`) in a second, narrower pass. Topic and time-range selection use
the summary's chunk and message indexes, so unselected chunks are never decompressed. A
truncated or unfinished file loads every complete chunk and says what was lost; a corrupt chunk
is skipped and reported.
"""

from __future__ import annotations

import contextlib
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
from hilrig.recording.chunks import (
    ChunkError,
    ChunkIndexError,
    Entries,
    batches,
    entries_of,
    indexed_entries,
)
from hilrig.recording.columns import INDEX_NAME, FixedChannel
from hilrig.recording.file_index import ChunkInfo, FileIndex
from hilrig.recording.generic import DecodeError, RawMessage, decode_frame
from hilrig.recording.mcap_records import MESSAGE_PREFIX, RECORD_HEADER, Channel, Schema
from hilrig.recording.msgdef import parse_schema, short_name
from hilrig.recording.scan import add_definitions, index_mapped, open_mcap
from hilrig.recording.schema import MESSAGE_ENCODING, SCHEMA_ENCODING
from hilrig.recording.session import utc_iso

PathLike = str | os.PathLike[str]
Progress = Callable[[int, int], None]


class RecordingWarning(UserWarning):
    """Data was lost or skipped while loading (truncated file, corrupt chunk, foreign channel)."""


@dataclass(frozen=True)
class Loaded:
    """What :func:`read` returns: the frames, one line per problem met while loading, and
    the file's index (``index.complete``: summary intact; ``index.truncation``: where it ends)."""

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

    ``progress(done, total)`` is called after each batch of chunks (counted in chunks).
    """
    p, mm = open_mcap(path)
    try:
        return read_mapped(p, mm, index_mapped(p, mm), topics, start_ns, end_ns, progress)
    finally:
        with contextlib.suppress(BufferError):  # a view still held by an error's traceback
            mm.close()


def read_mapped(
    path: Path,
    mm: mmap.mmap,
    index: FileIndex,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
    progress: Progress | None = None,
) -> Loaded:
    """:func:`read` of a file already opened and indexed; what is found damaged while reading
    is added to ``index.damage``."""
    return _Load(mm, index, topics, start_ns, end_ns, progress).run()


class _Channel:
    """One selected channel: its fast columns, or - once it proves variable - raw messages."""

    def __init__(self, path: Path, channel: Channel, schema: Schema, count: int) -> None:
        self.path, self.channel, self.schema, self.count = path, channel, schema, count
        self.fixed: FixedChannel | None = None
        self.generic = False
        self.raw: list[RawMessage] = []

    def gather(self, data: npt.NDArray[np.uint8], offsets: npt.NDArray[np.int64]) -> None:
        """Take the records at ``offsets`` of a batch; a misfit turns the channel generic."""
        if self.generic:
            return
        if self.fixed is None:
            self.fixed = self._fixed_layout(data, int(offsets[0]))
        if self.fixed is None or not self.fixed.gather(data, offsets):
            self.generic, self.fixed = True, None  # read again, message by message

    def _fixed_layout(self, data: npt.NDArray[np.uint8], offset: int) -> FixedChannel | None:
        _, length = RECORD_HEADER.unpack_from(data.data, offset)
        record = data[offset : offset + RECORD_HEADER.size + length].tobytes()
        try:
            defs = parse_schema(self.schema.name, self.schema.data.decode())
            message = record[MESSAGE_PREFIX.size :]
            layout = layout_of(defs, short_name(self.schema.name), message)
        except (LayoutError, RecordingError, UnicodeDecodeError):
            return None
        return FixedChannel(layout, record, self.count)

    def frame(self) -> pd.DataFrame:
        """The channel's frame; raises RecordingError if its messages do not decode."""
        if self.fixed is not None:
            return self.fixed.frame()
        if not self.raw:
            columns = {"publish_time_ns": np.empty(0, np.int64), "sequence": np.empty(0, np.uint32)}
            return pd.DataFrame(columns, index=pd.Index(np.empty(0, np.int64), name=INDEX_NAME))
        try:
            return decode_frame(self.schema, self.raw)
        except DecodeError as err:
            raise RecordingError(f"{self.path}: topic {self.channel.topic}: {err}") from err


def _raw_messages(data: bytes | memoryview, offsets: Iterable[int]) -> list[RawMessage]:
    out: list[RawMessage] = []
    for offset in offsets:
        _, length, _, sequence, log, publish = MESSAGE_PREFIX.unpack_from(data, offset)
        end = offset + RECORD_HEADER.size + length
        out.append((log, publish, sequence, bytes(data[offset + MESSAGE_PREFIX.size : end])))
    return out


class _Load:
    """One file's load: choose chunks, inflate them in batches, gather each channel's columns."""

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
        self.topics = (
            None if topics is None else {topics} if isinstance(topics, str) else set(topics)
        )
        self.start = 0 if start_ns is None else start_ns
        self.end = 2**64 if end_ns is None else end_ns
        self.problems: list[str] = []
        self.channels: dict[int, _Channel] = {}
        self.refused: set[int] = set()
        self.hints: dict[int, Entries | None] = {}  # each chunk's message index, unfiltered
        self.entries: dict[int, Entries | None] = {}  # selected messages; None: not known yet
        self.unknown: dict[int, int] = {}  # messages of channels without a channel record

    def run(self) -> Loaded:
        chunks = self._chunks()
        self.entries = {c.offset: self._entries(c) for c in chunks}
        counts: dict[int, int] = {}
        for found in self.entries.values():
            for cid, (_, offsets) in (found or {}).items():
                counts[cid] = counts.get(cid, 0) + len(offsets)
        done = 0
        for batch in batches(self.mm, chunks):
            for chunk, err in batch.errors:
                self._skipped(chunk, err)
            good = [(c, base) for c, base in batch.chunks if self._verify(batch.data, c, base)]
            self._gather(batch.data, good, counts)
            done += len(batch.chunks) + len(batch.errors)
            if self.progress is not None:
                self.progress(done, len(chunks))
        self._read_generic(chunks, self.entries)
        self._check_topics()
        for cid, count in sorted(self.unknown.items()):
            detail = f"{count} messages of channel {cid}, which has no (intact) channel record"
            self.index.damaged("chunk records", 0, detail + ", were skipped")
        frames = {c.channel.topic: c.frame() for c in self.channels.values()}
        problems = (*self.index.problems(), *self.problems)
        return Loaded(dict(sorted(frames.items())), problems, self.index)

    def _skipped(self, chunk: ChunkInfo, err: Exception) -> None:
        self.entries[chunk.offset] = {}
        span = f"{utc_iso(chunk.start_ns)} to {utc_iso(chunk.end_ns)}"
        end = chunk.offset + chunk.length
        self.index.damaged("chunk record", chunk.offset, f"{err}; its messages {span} skipped", end)

    def _verify(self, data: npt.NDArray[np.uint8], chunk: ChunkInfo, base: int) -> bool:
        """Check the chunk's message index against its records (or walk them); False if they
        cannot be read."""
        view = data.data[base : base + chunk.uncompressed_size]
        hint = self.hints.get(chunk.offset)
        try:
            found, definitions, wrong = entries_of(view, hint)
        except ChunkError as err:
            self._skipped(chunk, err)
            return False
        add_definitions(self.index, bytes(view), definitions)
        if found is not hint or self.entries[chunk.offset] is None:
            self.entries[chunk.offset] = self._filtered(found)
        if wrong:
            detail = "they do not match the chunk's messages; the chunk was read without them"
            self.index.damaged("message index records of the chunk", chunk.offset, detail)
        for cid, (times, _) in found.items():
            if cid not in self.index.channels:
                self.unknown[cid] = self.unknown.get(cid, 0) + len(times)
        return True

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

    def _entries(self, chunk: ChunkInfo) -> Entries | None:
        """Selected channels' messages in ``chunk`` within the time range, from its index;
        None when the chunk must be scanned after decompression."""
        try:
            found = indexed_entries(self.mm, chunk)
        except ChunkIndexError as err:
            self.index.damaged("message index records of the chunk", chunk.offset, str(err))
            found = None
        self.hints[chunk.offset] = found
        if found is None or not set(found) <= set(self.index.channels):
            return None
        inside = self.start <= chunk.start_ns and chunk.end_ns < self.end
        return self._filtered(found, inside=inside)

    def _filtered(self, found: Entries, *, inside: bool = False) -> Entries:
        """The selected channels' entries; those in the time range unless ``inside`` says the
        whole chunk is."""
        out: Entries = {}
        for cid, (times, offsets) in found.items():
            channel = self.index.channels.get(cid)
            if channel is None or not self._selected(channel) or cid in self.refused:
                continue
            if inside:
                out[cid] = (times, offsets)
                continue
            keep = (times >= self.start) & (times < self.end)
            out[cid] = (times, offsets) if keep.all() else (times[keep], offsets[keep])
        return out

    def _gather(
        self,
        data: npt.NDArray[np.uint8],
        chunks: list[tuple[ChunkInfo, int]],
        counts: dict[int, int],
    ) -> None:
        offsets: dict[int, list[npt.NDArray[np.int64]]] = {}
        for chunk, base in chunks:
            for cid, (_, positions) in (self.entries[chunk.offset] or {}).items():
                if len(positions):
                    offsets.setdefault(cid, []).append(positions + base)
        for cid, parts in offsets.items():
            channel = self._channel(cid, counts.get(cid, 0))
            if channel is not None:
                channel.gather(data, np.concatenate(parts) if len(parts) > 1 else parts[0])

    def _channel(self, channel_id: int, count: int = 0) -> _Channel | None:
        """The selected channel ``channel_id`` (created on first use), None if not selected.

        Channels that are not ROS 2 CDR are refused: an error if asked for by topic, else a
        reported skip."""
        existing = self.channels.get(channel_id)
        if existing is not None or channel_id in self.refused:
            return existing
        channel = self.index.channels.get(channel_id)
        if channel is None or not self._selected(channel):
            return None
        schema = self.index.schemas.get(channel.schema_id)
        if schema is None or schema.encoding != SCHEMA_ENCODING:
            problem = f"schema encoding {schema.encoding!r}" if schema else "no schema"
        elif channel.message_encoding != MESSAGE_ENCODING:
            problem = f"message encoding {channel.message_encoding!r}"
        else:
            created = _Channel(self.index.path, channel, schema, count)
            self.channels[channel_id] = created
            return created
        line = f"{self.index.path}: topic {channel.topic} has {problem}, not ros2msg/cdr"
        if self.topics is not None:
            raise RecordingError(line)
        self.problems.append(line + "; skipped")
        self.refused.add(channel_id)
        return None

    def _read_generic(self, chunks: list[ChunkInfo], entries: dict[int, Entries | None]) -> None:
        """Second pass, message by message, for channels without a fixed layout."""
        loose = self._loose_messages()
        generic = {cid for cid, c in self.channels.items() if c.generic or cid in loose}
        if not generic:
            return
        needed = [c for c in chunks if not generic.isdisjoint(entries.get(c.offset) or {})]
        for batch in batches(self.mm, needed):
            for chunk, base in batch.chunks:
                for cid, (_, positions) in (entries[chunk.offset] or {}).items():
                    if cid in generic:
                        found = _raw_messages(batch.data.data, (positions + base).tolist())
                        self.channels[cid].raw.extend(found)
        for cid, messages in loose.items():
            self.channels[cid].raw.extend(messages)
        for cid in generic:
            self.channels[cid].generic, self.channels[cid].fixed = True, None

    def _loose_messages(self) -> dict[int, list[RawMessage]]:
        """Selected messages written outside chunks (rare: unchunked files)."""
        loose: dict[int, list[RawMessage]] = {}
        for offset in self.index.loose_messages:
            (message,) = _raw_messages(memoryview(self.mm), [offset])
            channel_id = MESSAGE_PREFIX.unpack_from(self.mm, offset)[2]
            if self._channel(channel_id) is not None and self.start <= message[0] < self.end:
                loose.setdefault(channel_id, []).append(message)
        return loose

    def _check_topics(self) -> None:
        """Unknown topics are an error, and so is a file with channels but none readable."""
        known = {c.topic for c in self.index.channels.values()}
        missing = sorted((self.topics or set()) - known)
        if missing:
            have = ", ".join(sorted(known))
            raise RecordingError(f"{self.index.path}: no topic {', '.join(missing)} (has {have})")
        for cid in self.index.channels:
            self._channel(cid)
        if self.refused and not self.channels:
            raise RecordingError(self.problems[-1].removesuffix("; skipped") + "; nothing to read")
