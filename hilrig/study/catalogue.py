"""The catalogue of a study: every recording under a folder, described from its metadata.

``index(root)`` finds every ``*.mcap`` under ``root`` (hidden folders skipped) and describes
each from its index, metadata records and ``/events`` topic (the loop's collision and fault
log, a few messages: :mod:`.glance`), without reading the rest of its data: session, subject,
controller and parameters, scenario and its settings, body region, duration, collisions,
faults, and the loop's figures (ticks, dropped rows, hold ticks, missed deadlines). What it
read is kept in ``root/.hilrig-study/files.parquet`` with each file's size and modification
time, so indexing again reads only new or changed files.

A session is one row, keyed by its files: one file, or the parts of one split session (the
files its writer split, same session id); files are never joined by their id alone. Its key
(the ``session`` column) is its session id, or ``ID@PATH`` (its first file) when other files
of the study claim that id too: each such session is flagged ``duplicate-id``. Its ``flags``
name what may make it unfit for the study (:data:`FLAGS`); an unreadable file is a row of its
own, flagged ``unreadable``, keyed by its path, with the reason in ``problem``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from hilrig.errors import HilrigError, StudyError
from hilrig.recording.outcome import ran_its_course
from hilrig.recording.session import utc_iso
from hilrig.recording.session_ids import written_as
from hilrig.study.glance import glance
from hilrig.study.kept import keep, read_kept

STORE = ".hilrig-study"  # the study's own files, beside the data
FILES = "files.parquet"
FORMAT = "hilrig-study-files/1"
MISSED_FLAG_PCT = 0.1  # a session missing more deadlines than this is flagged
#: Quality flags, and what each means.
FLAGS = {
    "unreadable": "not a readable hilrig recording (see problem)",
    "incomplete": "the file is truncated or damaged: part of the session is missing",
    "unfinished": "no outcome record: the session did not end cleanly (or was recovered)",
    "ended-early": "the session ended before its time: stopped or a fault (see ended_by)",
    "dropped": "the recorder dropped rows",
    "holds": "the robot held its pose on some ticks (stale data, a fault or a stop)",
    "missed": f"more than {MISSED_FLAG_PCT} % of the loop's deadlines were missed",
    "duplicate-id": "another file of the study claims its session id (a copy, or an id of a "
    "second's resolution): each is a session of its own, keyed ID@PATH",
}
#: One row per file, as stored (times as ns, settings and parameters as JSON text).
FILE_COLUMNS = (
    "path",
    "size_bytes",
    "mtime_ns",
    "session",
    "part",
    "subject",
    "controller",
    "params",
    "scenario",
    "settings",
    "body_region",
    "start_ns",
    "end_ns",
    "collisions",
    "faults",
    "ticks",
    "dropped",
    "hold_ticks",
    "missed_deadlines",
    "complete",
    "ended_cleanly",
    "ended_by",
    "problem",
)
#: One row per session, as shown.
CATALOGUE_COLUMNS = (
    "session",
    "subject",
    "controller",
    "condition",
    "params",
    "scenario",
    "settings",
    "body_region",
    "start_utc",
    "duration_s",
    "collisions",
    "faults",
    "ticks",
    "dropped",
    "hold_ticks",
    "missed_pct",
    "complete",
    "ended_cleanly",
    "flags",
    "excluded",
    "path",
    "parts",
    "size_bytes",
)

Progress = Callable[[int, int], None]  # (files read, files to read)


def recordings(root: Path) -> list[Path]:
    """Every ``*.mcap`` under ``root``, sorted, hidden folders and files skipped."""
    if not root.is_dir():
        raise StudyError(f"{root}: not a folder of recordings")
    found = []
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        found += [Path(folder) / f for f in files if f.endswith(".mcap") and not f.startswith(".")]
    return sorted(found)


def index(root: Path, *, progress: Progress | None = None) -> tuple[pd.DataFrame, int]:
    """The catalogue's file table of ``root`` (stored again when anything changed) and how many
    files were read; files unchanged since the last index are not opened."""
    store = root / STORE / FILES
    known = _stored(store)
    rows, read = [], 0
    paths = recordings(root)
    stale = []
    for path in paths:
        name = path.relative_to(root).as_posix()
        stat = path.stat()
        row = known.get(name)
        if row is None or (row["size_bytes"], row["mtime_ns"]) != (stat.st_size, stat.st_mtime_ns):
            stale.append((name, path, stat))
        else:
            rows.append(row)
    for done, (name, path, stat) in enumerate(stale, 1):
        rows.append(describe(path, name, stat.st_size, stat.st_mtime_ns))
        read += 1
        if progress is not None:
            progress(done, len(stale))
    files = pd.DataFrame(rows, columns=list(FILE_COLUMNS)).sort_values("path", ignore_index=True)
    if read or len(known) != len(files):
        _store(files, store)
    return files, read


def describe(path: Path, name: str, size: int, mtime_ns: int) -> dict[str, object]:
    """One file's row of the file table (unreadable files too: ``problem`` says why)."""
    row: dict[str, object] = dict.fromkeys(FILE_COLUMNS, None)
    row |= {"path": name, "size_bytes": size, "mtime_ns": mtime_ns, "session": name, "part": 0}
    row |= {"complete": False, "ended_cleanly": False, "ended_by": "", "problem": ""}
    try:
        seen = glance(path)
    except HilrigError as err:
        return row | {"problem": str(err)}
    session = seen.session
    if session is None:
        return row | {"problem": "no session metadata; is it a hilrig recording?"}
    row |= {
        "session": session.session_id,
        "part": seen.part,
        "subject": session.subject_id,
        "controller": session.controller,
        "params": json.dumps(dict(session.controller_params), sort_keys=True),
        "scenario": session.scenario,
        "settings": json.dumps(dict(session.scenario_settings), sort_keys=True),
        "body_region": session.body_region,
        "start_ns": seen.start_ns,
        "end_ns": seen.end_ns,
        "complete": seen.complete,
        "problem": seen.problem,
        "collisions": seen.collisions,
        "faults": seen.faults,
    }
    outcome = seen.outcome
    if outcome is not None:
        row |= {
            "ticks": outcome.ticks,
            "dropped": outcome.recorder_drops,
            "hold_ticks": outcome.hold_ticks,
            "missed_deadlines": outcome.missed_deadlines,
            "ended_cleanly": True,
            "ended_by": outcome.ended_by,
        }
    elif seen.loop is not None:  # the last loop diagnostics say what was counted
        row |= {"ticks": seen.loop.tick, "dropped": seen.loop.recorder_drops}
        row |= {"missed_deadlines": seen.loop.overruns}
    return row


def sessions(files: pd.DataFrame) -> pd.DataFrame:
    """The catalogue (:data:`CATALOGUE_COLUMNS`, ``excluded`` empty): one row per session, the
    parts of a split session joined, in the order of their first file's path."""
    rows = [_session_row(key, group, twin) for key, group, twin in _by_session(files)]
    frame = pd.DataFrame(rows, columns=list(CATALOGUE_COLUMNS))
    frame["condition"] = conditions(frame)
    return frame


def session_files(files: pd.DataFrame) -> dict[str, list[str]]:
    """Each session's key (the catalogue's ``session``) and its files' paths in part order."""
    return {key: list(group["path"]) for key, group, _ in _by_session(files)}


def twins(catalogue: pd.DataFrame, session_id: str) -> list[str]:
    """The keys of the sessions that claim ``session_id`` when several do (else none)."""
    return [k for k in catalogue["session"].astype(str) if k.startswith(f"{session_id}@")]


def _by_session(files: pd.DataFrame) -> Iterator[tuple[str, pd.DataFrame, bool]]:
    """Each session's key, files (in part order) and whether another session claims its id, in
    the order of their first file's path. A session's files are one file, or the parts one
    writer split (same id, same folder and name but the part number); unreadable: alone."""
    readable = files["subject"].notna()
    origins = [
        written_as(str(p), int(n)) for p, n in zip(files["path"], files["part"], strict=True)
    ]
    same = files["session"].astype(str) + "\0" + pd.Series(origins, files.index, dtype=str)
    found = [
        g.sort_values("part")
        for _, g in files.groupby(same.where(readable, files["path"]), sort=False)
    ]
    claimed = pd.Series([str(g["session"].iloc[0]) for g in found if g["subject"].notna().iloc[0]])
    claims = claimed.value_counts()
    for group in found:
        session, first = str(group["session"].iloc[0]), str(group["path"].iloc[0])
        twin = bool(group["subject"].notna().iloc[0]) and claims.get(session, 0) > 1
        yield (f"{session}@{first}" if twin else session), group, twin


def _session_row(key: str, parts: pd.DataFrame, twin: bool) -> dict[str, object]:
    first, last = parts.iloc[0], parts.iloc[-1]
    readable = first["subject"] is not None and not pd.isna(first["subject"])
    flags = [] if readable else ["unreadable"]
    if readable:
        flags += ["duplicate-id"] if twin else []
        flags += [] if bool(parts["complete"].all()) else ["incomplete"]
        flags += [] if bool(last["ended_cleanly"]) else ["unfinished"]
        flags += [] if ran_its_course(str(last["ended_by"])) else ["ended-early"]
        flags += ["dropped"] if _total(parts, "dropped") else []
        flags += ["holds"] if _total(parts, "hold_ticks") else []
    ticks = _total(parts, "ticks")
    missed = 100.0 * _total(parts, "missed_deadlines") / ticks if ticks else 0.0
    flags += ["missed"] if missed > MISSED_FLAG_PCT else []
    start, end = parts["start_ns"].min(), parts["end_ns"].max()
    timed = readable and not (pd.isna(start) or pd.isna(end))
    return {
        "session": key,
        "subject": first["subject"] if readable else "",
        "controller": first["controller"] if readable else "",
        "params": first["params"] if readable else "{}",
        "scenario": first["scenario"] if readable else "",
        "settings": first["settings"] if readable else "{}",
        "body_region": first["body_region"] if readable else "",
        "start_utc": utc_iso(int(start)) if timed else "",
        "duration_s": (int(end) - int(start)) / 1e9 if timed else float("nan"),
        "collisions": _total(parts, "collisions"),
        "faults": _total(parts, "faults"),
        "ticks": ticks,
        "dropped": _total(parts, "dropped"),
        "hold_ticks": _total(parts, "hold_ticks"),
        "missed_pct": missed,
        "complete": bool(parts["complete"].all()),
        "ended_cleanly": bool(last["ended_cleanly"]),
        "flags": ",".join(flags),
        "excluded": "",
        "path": first["path"],
        "parts": len(parts),
        "size_bytes": int(parts["size_bytes"].sum()),
    }


def _total(parts: pd.DataFrame, column: str) -> int:
    return int(pd.to_numeric(parts[column], errors="coerce").fillna(0).sum())


def conditions(catalogue: pd.DataFrame) -> list[str]:
    """Each session's condition: its controller, with its parameters where the study ran that
    controller with more than one parameter set (``adaptive {"b0": 40.0}``)."""
    sets = catalogue.groupby("controller")["params"].nunique()
    return [
        c if sets.get(c, 1) <= 1 or p in ("", "{}") else f"{c} {p}"
        for c, p in zip(catalogue["controller"], catalogue["params"], strict=True)
    ]


def settings_columns(catalogue: pd.DataFrame) -> pd.DataFrame:
    """The catalogue with each scalar scenario setting as a column of its own (for --where),
    named as the setting unless the catalogue has a column of that name."""
    parsed = [json.loads(s or "{}") for s in catalogue["settings"]]
    names = dict.fromkeys(k for d in parsed for k, v in d.items() if isinstance(v, int | float))
    extra = {
        name if name not in catalogue.columns else f"scenario_{name}": [
            float(d[name]) if isinstance(d.get(name), int | float) else np.nan for d in parsed
        ]
        for name in names
    }
    return catalogue.assign(**extra)


def _stored(store: Path) -> dict[str, dict[str, object]]:
    """The stored file table by path; empty when there is none or it is of another format."""
    table = read_kept(store, FORMAT, FILE_COLUMNS)
    if table is None:
        return {}
    table = table.astype(object).where(table.notna(), None)
    return {
        str(row["path"]): {str(k): v for k, v in row.items()} for row in table.to_dict("records")
    }


def _store(files: pd.DataFrame, store: Path) -> None:
    try:
        keep(store, files, FORMAT)
    except OSError as err:
        raise StudyError(f"{store}: cannot store the catalogue ({err.strerror or err})") from err
