"""One recording at a glance, for the catalogue: its index read once, its data left alone.

The file is indexed once (summary, chunk index, metadata: ``hilrig.recording.scan``); from that
index come the session record, the loop's ``outcome`` record, the log-time span and the
``/events`` messages (the few chunks that hold them are decompressed). Nothing else of the data
is read, so neither is the data section's CRC (``hilrig info --check`` reads every byte). A
file without an outcome record falls back to :func:`hilrig.recording.inspect` for the loop's
last ``/diagnostics/loop`` counters.
"""

from __future__ import annotations

import contextlib
import mmap
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hilrig.recording import inspect
from hilrig.recording.file_index import FileIndex
from hilrig.recording.info import LoopCounters, outcome_of
from hilrig.recording.outcome import SessionOutcome
from hilrig.recording.reader import RecordingWarning, read_mapped
from hilrig.recording.samples import EventKind
from hilrig.recording.scan import index_mapped, open_mcap
from hilrig.recording.session import SessionInfo

EVENTS_TOPIC = "/events"


@dataclass(frozen=True)
class Glance:
    """What the catalogue needs of one file (``problem``: one line, "" when none)."""

    session: SessionInfo | None
    part: int
    start_ns: int | None
    end_ns: int | None
    complete: bool
    problem: str
    collisions: int
    faults: int
    outcome: SessionOutcome | None
    loop: LoopCounters | None


def glance(path: Path) -> Glance:
    """``path`` at a glance; RecordingError (one line) when it is not an MCAP file at all or
    its session record is damaged."""
    p, mm = open_mcap(path)
    try:
        index = index_mapped(p, mm)
        session = index.session_info()
        outcome, outcome_problem = outcome_of(index)
        collisions, faults = _events(p, mm, index)
        start, end = _span(index)
        problems = index.problems()
        part = index.values.get("session", {}).get("part", "0")
        found = Glance(
            session=session,
            part=int(part) if part.isdigit() else 0,
            start_ns=start,
            end_ns=end,
            complete=index.complete and not problems,
            problem="; ".join(problems) or (outcome_problem or ""),
            collisions=collisions,
            faults=faults,
            outcome=outcome,
            loop=None,
        )
    finally:
        with contextlib.suppress(BufferError):
            mm.close()
    if outcome is None and session is not None:  # the loop's last counters say what it counted
        return replace(found, loop=inspect(path, crc=False).loop)
    return found


def _span(index: FileIndex) -> tuple[int | None, int | None]:
    """First and last log time: the summary's statistics, else the chunks'."""
    stats = index.statistics
    if stats is not None and stats.message_count:
        return stats.message_start_time, stats.message_end_time
    if not index.chunks:
        return None, None
    return min(c.start_ns for c in index.chunks), max(c.end_ns for c in index.chunks)


def _events(path: Path, mm: mmap.mmap, index: FileIndex) -> tuple[int, int]:
    """Collision starts and faults in the file's ``/events`` (0, 0 without any)."""
    if not any(c.topic == EVENTS_TOPIC for c in index.channels.values()):
        return 0, 0
    with warnings.catch_warnings():  # what a damaged file lost is in its problems
        warnings.simplefilter("ignore", RecordingWarning)
        loaded = read_mapped(path, mm, index, [EVENTS_TOPIC])
    events = loaded.frames.get(EVENTS_TOPIC)
    if events is None or "kind" not in events:
        return 0, 0
    kinds = events["kind"].to_numpy()
    return int(np.sum(kinds == EventKind.COLLISION_START)), int(np.sum(kinds == EventKind.FAULT))
