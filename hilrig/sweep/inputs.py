"""A sweep's inputs: files, folders and study folders, each file a *source* of the output.

Inputs are files (a recorded session, or a CSV/Parquet force table), folders (every ``*.mcap``
under them, hidden folders skipped) and study folders (one with ``.hilrig-study`` or
``study.toml``: the sessions of its catalogue, without the ones ``study.toml`` excludes and the
unreadable ones). Each input is a *source* named by its path relative to the folder given (a
file given alone: its name); a split session's parts are sources of their own, as replay reads
one file at a time.

Events a study excludes (``study.toml`` ``event = N``) are numbered as the study numbers them:
by analysing the recorded session (all its parts together, hilrig's default event settings).
A sweep's task finds events in the force its own run met, in one file, so it cannot go by
number: each excluded event travels with its session's files as its group and time window,
and a task leaves out the rows of its events of that group whose windows overlap it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hilrig.errors import SweepError
from hilrig.replay.inputs import MCAP_SUFFIXES, TABLE_SUFFIXES
from hilrig.replay.job import check_closed_input
from hilrig.study.catalogue import STORE, index, recordings, session_files, sessions
from hilrig.study.observations import AnalysisSettings, events_of, jobs
from hilrig.study.study_file import STUDY_FILE, StudyFile, read_study

NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class ExcludedEvent:
    """An event a study excludes: its group (``cartesian``, ``joint``) and its time window in
    ns since the epoch (UTC), as the study's analysis of the recording found it."""

    group: str
    start_ns: int
    end_ns: int


@dataclass(frozen=True)
class Input:
    """A file to replay: its path, its name in the output (``source``) and the events of it
    that a study excludes."""

    path: Path
    source: str
    excluded: tuple[ExcludedEvent, ...] = ()


@dataclass(frozen=True)
class Inputs:
    """The sweep's inputs, and what was left out of study folders and why (lines to show)."""

    files: tuple[Input, ...]
    notes: tuple[str, ...] = ()


def is_study(folder: Path) -> bool:
    """Whether ``folder`` is a study (it has a catalogue or a study file)."""
    return (folder / STORE).is_dir() or (folder / STUDY_FILE).is_file()


def find_inputs(paths: Sequence[Path], *, closed_loop: bool = False) -> Inputs:
    """The sweep's inputs under ``paths`` (see the module docstring). Raises SweepError (one
    line) for a path that is neither, a file of another kind, two sources of the same name or
    nothing to sweep; ReplayError for an input closed loop cannot replay."""
    found: list[Input] = []
    notes: list[str] = []
    for path in paths:
        if path.is_dir():
            if is_study(path):
                chosen, note = study_inputs(path)
                found += chosen
                notes.append(note)
            else:
                found += [
                    Input(f.resolve(), f.relative_to(path).as_posix()) for f in recordings(path)
                ]
        elif path.is_file():
            if path.suffix.lower() not in MCAP_SUFFIXES + TABLE_SUFFIXES:
                known = ", ".join(MCAP_SUFFIXES + TABLE_SUFFIXES)
                raise SweepError(f"{path}: not an input to replay; known: {known} and folders")
            found.append(Input(path.resolve(), path.name))
        else:
            raise SweepError(f"{path}: no such file or folder")
    seen: dict[str, Path] = {}
    for item in found:
        if item.source in seen and seen[item.source] != item.path:
            raise SweepError(
                f"{seen[item.source]} and {item.path} would both be source {item.source!r}; "
                "sweep them into separate --out folders"
            )
        seen[item.source] = item.path
    unique = tuple({item.source: item for item in found}.values())
    if not unique:
        raise SweepError(f"nothing to sweep in {', '.join(map(str, paths))}: no .mcap sessions")
    if closed_loop:
        for item in unique:
            check_closed_input(item.path)
    return Inputs(unique, tuple(notes))


def study_inputs(root: Path) -> tuple[list[Input], str]:
    """The files of a study's included sessions (the catalogue indexed first) with the events
    it excludes, and a line saying what was left out."""
    files, _ = index(root)
    catalogue = sessions(files)
    study = read_study(root)
    excluded = {e.session for e in study.exclusions if e.event is None}
    unreadable = set(catalogue.loc[catalogue["flags"].str.contains("unreadable"), "session"])
    kept = [s for s in catalogue["session"] if s not in excluded and s not in unreadable]
    parts = session_files(files)
    windows, found, missing = _event_windows(root, catalogue, files, study, set(kept))
    chosen = [
        Input((root / path).resolve(), path, windows.get(session, ()))
        for session in sorted(kept)
        for path in parts[session]
    ]
    left = len(set(catalogue["session"]) & excluded)
    note = (
        f"study {root}: {len(kept)} sessions ({len(chosen)} files); left out: {left} excluded "
        f"in {STUDY_FILE}, {len(unreadable)} unreadable"
    )
    if found or missing:
        note += (
            f"; events excluded in {STUDY_FILE}: {found} left out (by group and time), "
            f"{missing} not in their sessions"
        )
    return chosen, note


def _event_windows(
    root: Path, catalogue: pd.DataFrame, files: pd.DataFrame, study: StudyFile, kept: set[str]
) -> tuple[dict[str, tuple[ExcludedEvent, ...]], int, int]:
    """Per kept session, the windows of the events ``study`` excludes (the study's analyses,
    stored ones reused); how many were found, and how many name an event the session lacks."""
    wanted = {(e.session, e.event) for e in study.exclusions if e.event is not None}
    wanted = {(s, n) for s, n in wanted if s in kept}
    if not wanted:
        return {}, 0, 0
    settings = AnalysisSettings()
    named = catalogue[catalogue["session"].isin({s for s, _ in wanted})]
    tables, _ = events_of(jobs(root, named, files, settings), settings)
    windows: dict[str, list[ExcludedEvent]] = {}
    found = 0
    for session, number in sorted(wanted):
        table = tables.get(session)
        rows = table[table["event"] == number] if table is not None else None
        if rows is None or rows.empty:
            continue
        row = rows.iloc[0]
        t0_ns = int(row["t0_ns"])
        start_ns = t0_ns + round(float(row["start_s"]) * NS_PER_S)
        end_ns = t0_ns + round(float(row["end_s"]) * NS_PER_S)
        windows.setdefault(session, []).append(ExcludedEvent(str(row["group"]), start_ns, end_ns))
        found += 1
    return {s: tuple(w) for s, w in windows.items()}, found, len(wanted) - found
