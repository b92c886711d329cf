"""What an MCAP file holds, by file offset, and what is damaged in it: the index every reader
builds (:mod:`.scan`) and works from."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from hilrig.errors import RecordingError
from hilrig.recording.damage import Damage
from hilrig.recording.mcap_records import Channel, Schema, Statistics
from hilrig.recording.parse import IndexRef
from hilrig.recording.session import SESSION_METADATA, SessionInfo, TimeWindow, utc_iso


@dataclass(frozen=True)
class ChunkInfo:
    """A chunk record: file ``offset`` and total ``length`` of the record, log-time span (ns),
    where its compressed data starts and, per channel id, the file offset of its MessageIndex.
    ``uncompressed_crc`` is None when the chunk's header is damaged (its data must then carry a
    checksum of its own)."""

    offset: int
    length: int
    start_ns: int
    end_ns: int
    compression: str
    data_offset: int
    compressed_size: int
    uncompressed_size: int
    uncompressed_crc: int | None
    message_index_offsets: dict[int, int]


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
    """What an MCAP file holds, by file offset. ``complete``: the summary and footer were read
    and checked; ``truncation``: where an unfinished file ends; ``damage``: what is broken."""

    path: Path
    size: int
    profile: str = ""
    library: str = ""
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    definition_offsets: dict[tuple[int, int], int] = field(default_factory=dict)
    chunks: list[ChunkInfo] = field(default_factory=list)
    metadata: list[IndexRef] = field(default_factory=list)
    values: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[IndexRef] = field(default_factory=list)
    loose_messages: list[int] = field(default_factory=list)  # offsets of messages outside chunks
    incomplete_indexes: set[int] = field(default_factory=set)  # chunks with an index lost
    complete: bool = False
    truncation: Truncation | None = None
    damage: list[Damage] = field(default_factory=list)
    session: SessionInfo | None = None
    window: TimeWindow = field(default_factory=TimeWindow)
    data_end: int | None = None  # offset of the DataEnd record
    data_crc: int = 0  # the data section's CRC the DataEnd record gives; 0: none
    statistics: Statistics | None = None  # the summary's, when it is whole

    def damaged(self, what: str, offset: int, detail: str, end: int | None = None) -> None:
        self.damage.append(Damage(what, offset, detail, end))

    def drop_metadata(self, name: str, detail: str) -> None:
        """The metadata records named ``name`` are damaged (``detail``): left out."""
        for ref in [r for r in self.metadata if r.name == name]:
            self.damaged(f"metadata record {name!r}", ref.offset, detail, ref.offset + ref.length)
            self.metadata.remove(ref)
        self.values.pop(name, None)

    def problems(self) -> list[str]:
        """One line per problem: where an unfinished file ends, a missing summary, damage."""
        lines = [d.line(self.path) for d in self.damage]
        if self.truncation is not None:
            lines.insert(0, describe_truncation(self))
        elif not self.complete:
            lines.insert(0, f"{self.path}: summary missing or damaged; indexed by scanning")
        return lines

    def session_info(self) -> SessionInfo | None:
        """The session record's contents; None if there is none. RecordingError (the damage
        line) if the record is damaged, or if hilrig wrote this damaged file and it has none."""
        for damage in self.damage:
            if damage.what in (f"metadata record {SESSION_METADATA!r}", "metadata record"):
                raise damage.error(self.path)
        if self.session is None and self.damage and self.library.startswith("hilrig/"):
            raise RecordingError(
                f"{self.path}: its session metadata record is missing; the file is damaged"
            )
        return self.session


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
    problem = (
        None
        if t.tail_start_ns is None or t.tail_end_ns is None
        else index.window.problem(t.tail_start_ns, t.tail_end_ns)
    )
    if t.tail_start_ns is not None and t.tail_end_ns is not None and problem is None:
        lost_s = (t.tail_end_ns - t.tail_start_ns) / 1e9
        line += f": messages from {utc_iso(t.tail_start_ns)} to {utc_iso(t.tail_end_ns)}"
        line += f" ({lost_s:.3f} s)"
    return line
