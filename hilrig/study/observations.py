"""A study's observations: every included session analysed once, each event's metrics on its
loaded axis, kept beside the data so a second report reads no recording again.

A session's analysis (:func:`hilrig.analysis.analyze`, the events and safety verdicts of
``hilrig analyze``) is stored in ``DIR/.hilrig-study/metrics/`` under a name derived from its
session id, with a key of what it was computed from (its files' names, sizes and modification
times, the analysis settings and hilrig's version); a stored analysis whose key differs is
computed again. Sessions are analysed in a process pool (one worker per core) when there are
several to do (forked, as replay's pools).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from hilrig import __version__
from hilrig.analysis import DEFAULT_EVENTS, EventConfig, analyze, load_session, metrics_frame
from hilrig.analysis.compare import DEFAULT_VERDICTS
from hilrig.analysis.verdict import VerdictConfig
from hilrig.errors import HilrigError, OutputError
from hilrig.study.catalogue import STORE, session_files
from hilrig.study.kept import keep, read_kept
from hilrig.study.records import STUDY_METRICS

METRICS = "metrics"
POOL_MIN_SESSIONS = 3  # fewer are analysed in this process
#: Per event of a session: where it is and its values (the loaded axis), as stored.
EVENT_COLUMNS = ("event", "group", "axis", "start_s", "end_s", "t0_ns", *STUDY_METRICS)
ABSOLUTE = ("peak_force", "impulse")  # compared as magnitudes

Done = Callable[[str], None]  # called with a session id as each analysis is ready


@dataclass(frozen=True)
class AnalysisSettings:
    """How sessions are analysed (``hilrig analyze``'s options)."""

    events: EventConfig = DEFAULT_EVENTS
    safety: VerdictConfig = DEFAULT_VERDICTS

    def key(self) -> str:
        return json.dumps({"events": asdict(self.events), "safety": asdict(self.safety)})


@dataclass(frozen=True)
class SessionJob:
    """One session to analyse: its id, files (in part order) and the stored result's path."""

    session: str
    paths: tuple[Path, ...]
    stored: Path
    key: str


def jobs(
    root: Path, catalogue: pd.DataFrame, files: pd.DataFrame, settings: AnalysisSettings
) -> list[SessionJob]:
    """A job per catalogue row, its files (in part order) from the catalogue's file table."""
    found = []
    parts = session_files(files)
    for session in catalogue["session"]:
        paths = tuple(root / p for p in parts[str(session)])
        stamp = [(p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in paths]
        key = json.dumps([stamp, settings.key(), __version__])
        name = hashlib.sha1(str(session).encode()).hexdigest()[:20] + ".parquet"
        found.append(SessionJob(str(session), paths, root / STORE / METRICS / name, key))
    return found


def events_of(
    jobs_: Sequence[SessionJob], settings: AnalysisSettings, *, done: Done | None = None
) -> tuple[dict[str, pd.DataFrame], dict[str, str]]:
    """Each session's event table (:data:`EVENT_COLUMNS`), from the store where it is current,
    and for sessions that cannot be analysed, why (one line)."""
    tables: dict[str, pd.DataFrame] = {}
    failed: dict[str, str] = {}
    todo = []
    for job in jobs_:
        table = _stored(job)
        if table is None:
            todo.append(job)
        else:
            tables[job.session] = table
            if done is not None:
                done(job.session)
    for job, outcome in _run(todo, settings):
        if isinstance(outcome, str):
            failed[job.session] = outcome
        else:
            tables[job.session] = outcome
            _store(job, outcome)
        if done is not None:
            done(job.session)
    return tables, failed


def _run(
    todo: list[SessionJob], settings: AnalysisSettings
) -> Iterator[tuple[SessionJob, pd.DataFrame | str]]:
    """Each job with its outcome, as they finish (forked workers, as replay's pools)."""
    if len(todo) < POOL_MIN_SESSIONS:
        yield from ((job, analyse(job, settings)) for job in todo)
        return
    from hilrig.replay.engine import local_cores

    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(min(local_cores(), len(todo)), mp_context=context) as pool:
        futures = {pool.submit(analyse, job, settings): job for job in todo}
        for future in as_completed(futures):
            yield futures[future], future.result()


def analyse(job: SessionJob, settings: AnalysisSettings) -> pd.DataFrame | str:
    """The session's event table, or why it cannot be analysed (one line)."""
    try:
        source = load_session(list(job.paths))
        analysis = analyze(source, events=settings.events, safety=settings.safety)
    except HilrigError as err:
        return str(err)
    loaded = loaded_events(metrics_frame([analysis]))
    table = loaded.loc[:, [c for c in EVENT_COLUMNS if c != "t0_ns"]]
    table = table.astype({"event": np.int64, "group": str, "axis": str})
    table = table.astype(dict.fromkeys(STUDY_METRICS, np.float64))
    table.insert(EVENT_COLUMNS.index("t0_ns"), "t0_ns", int(source.start_ns or 0))
    return table.reset_index(drop=True)


def loaded_events(metrics: pd.DataFrame, by: Sequence[str] = ()) -> pd.DataFrame:
    """Each event's row on its loaded axis (the largest |peak force|, the first of equal ones;
    a NaN peak counts as the largest, as ``np.argmax`` has it) of analysis's metrics rows,
    grouped by ``by`` and ``event``, peak force and impulse as magnitudes; rows by those keys."""
    keys = [pd.factorize(metrics[key], sort=True)[0] for key in [*by, "event"]]
    magnitude = np.abs(metrics["peak_force"].to_numpy(np.float64))
    rank = np.where(np.isnan(magnitude), np.inf, magnitude)
    order = np.lexsort((-rank, *reversed(keys)))  # stable: the first of equals leads
    ordered = np.column_stack([key[order] for key in keys])
    leads = np.ones(len(order), dtype=bool)
    leads[1:] = (ordered[1:] != ordered[:-1]).any(axis=1)
    loaded = metrics.iloc[order[leads]]
    return loaded.assign(**{m: loaded[m].abs() for m in ABSOLUTE})


def observations(
    catalogue: pd.DataFrame, tables: dict[str, pd.DataFrame], skip: set[tuple[str, int]]
) -> pd.DataFrame:
    """The long observations table (records.OBSERVATION_COLUMNS) of the catalogue's sessions
    that have an event table, without the (session, event) pairs in ``skip``."""
    parts = []
    for session, subject, condition in catalogue[["session", "subject", "condition"]].itertuples(
        index=False
    ):
        table = tables.get(str(session))
        if table is None or table.empty:
            continue
        kept = table[[(str(session), int(e)) not in skip for e in table["event"]]]
        long = kept.melt(
            id_vars=["event", "group", "axis"],
            value_vars=list(STUDY_METRICS),
            var_name="metric",
            value_name="value",
        )
        parts.append(long.assign(session=str(session), subject=subject, condition=condition))
    columns = ["session", "subject", "condition", "event", "group", "axis", "metric", "value"]
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=object) for c in columns})
    frame = pd.concat(parts, ignore_index=True)[columns]
    return frame.astype({"event": np.int64, "value": np.float64})


def _stored(job: SessionJob) -> pd.DataFrame | None:
    return read_kept(job.stored, job.key, EVENT_COLUMNS)


def _store(job: SessionJob, table: pd.DataFrame) -> None:
    with contextlib.suppress(OSError, OutputError):  # read-only folder: the analysis is not kept
        keep(job.stored, table, job.key)
