"""A study, from its folder to everything its report shows.

Steps: index the folder (catalogue), apply the study file's exclusions, analyse every included
session (stored analyses reused), take each event's observations, compute the statistics across
subjects, and pick each condition's representative event. Every number downstream is of the
included data only; the report lists what was left out and why:

- the study file's exclusions (``hilrig study exclude``), of sessions or single events;
- unreadable files, and sessions that cannot be analysed (no controller states), with the error.

Quality flags (dropped rows, hold ticks, missed deadlines, an incomplete file) do not exclude a
session by themselves: the report names the flagged sessions it kept, and the lab decides.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from hilrig import __version__
from hilrig.analysis import default_baseline
from hilrig.errors import StudyError
from hilrig.study import stats
from hilrig.study.catalogue import index, sessions, twins
from hilrig.study.curves import curves, representatives
from hilrig.study.observations import AnalysisSettings, events_of, jobs, observations
from hilrig.study.records import StudyReport
from hilrig.study.study_file import StudyFile, read_study

Step = Callable[[str, int, int], None]  # (what, done, of)


@dataclass(frozen=True)
class ReportOptions:
    """What the report compares and how (``hilrig report``'s options)."""

    baseline: str | None = None  # None: the study file's, else fixed, else the first
    analysis: AnalysisSettings = field(default_factory=AnalysisSettings)
    confidence: float = 0.95
    resamples: int = 9999
    seed: int = 0


def assemble(
    root: Path, options: ReportOptions, command: str, *, step: Step | None = None
) -> StudyReport:
    """The study under ``root`` as a :class:`StudyReport`; StudyError (one line) when it has
    no session or no event left to compare."""
    tell: Step = step or (lambda what, done, of: None)
    files, _ = index(root, progress=lambda done, of: tell("indexing", done, of))
    catalogue = sessions(files)
    if catalogue.empty:
        raise StudyError(f"{root}: no recordings (*.mcap) in it or its sub-folders")
    study = read_study(root)
    reasons, skip, notes = _exclusions(catalogue, study)
    unreadable = catalogue["flags"].str.contains("unreadable")
    for session in catalogue.loc[unreadable, "session"]:
        reasons.setdefault(str(session), "unreadable: " + _problem(files, str(session)))
    included = catalogue[~catalogue["session"].isin(list(reasons))]
    todo = jobs(root, included, files, options.analysis)
    counter = iter(range(1, len(todo) + 1))
    tables, failed = events_of(
        todo, options.analysis, done=lambda _: tell("analysing", next(counter), len(todo))
    )
    reasons |= {s: f"cannot be analysed: {why}" for s, why in failed.items()}
    catalogue["excluded"] = [reasons.get(str(s), "") for s in catalogue["session"]]
    kept = catalogue[catalogue["excluded"] == ""]
    found = observations(kept, tables, skip)
    notes += _missing_events(kept, tables, skip)
    if found.empty:
        raise StudyError(f"{root}: no collision events left to compare in the included sessions")
    conditions = list(dict.fromkeys(found["condition"]))
    baseline = options.baseline or study.baseline or default_baseline(conditions)
    if baseline not in conditions:
        known = ", ".join(conditions)
        raise StudyError(f"baseline {baseline!r} is not a condition; conditions: {known}")
    tell("statistics", 0, 1)
    values = stats.subject_values(found)
    design, sentences = stats.design(found, baseline)
    compared = stats.comparisons(
        values,
        baseline,
        confidence=options.confidence,
        resamples=options.resamples,
        seed=options.seed,
    )
    tell("statistics", 1, 1)
    paths = {job.session: list(job.paths) for job in todo}
    chosen = representatives(found)
    return StudyReport(
        name=study.name or root.resolve().name,
        created_utc=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        software_version=__version__,
        command=command,
        baseline=baseline,
        catalogue=catalogue,
        exclusions=_removed(catalogue, study, tables, skip),
        design=design,
        design_text=sentences,
        observations=found,
        subject_values=values,
        distributions=stats.distributions(values),
        comparisons=compared,
        curves=curves(chosen, tables, paths),
        notes=(*notes, *_flag_notes(kept)),
    )


def _exclusions(
    catalogue: pd.DataFrame, study: StudyFile
) -> tuple[dict[str, str], set[tuple[str, int]], list[str]]:
    """Sessions excluded (with reasons), events excluded, and notes on exclusions of nothing."""
    known = set(catalogue["session"].astype(str))
    reasons: dict[str, str] = {}
    skip: set[tuple[str, int]] = set()
    notes = []
    for e in study.exclusions:
        claimed = twins(catalogue, e.session)
        if claimed:
            notes.append(
                f"study.toml excludes {e.target}, but {len(claimed)} sessions claim that id: "
                f"name one as {' or '.join(claimed)}"
            )
        elif e.session not in known:
            notes.append(f"study.toml excludes {e.target}, which is not in the catalogue")
        elif e.event is None:
            reasons[e.session] = e.reason
        else:
            skip.add((e.session, e.event))
    return reasons, skip, notes


def _problem(files: pd.DataFrame, session: str) -> str:
    rows = files[files["path"] == session]
    return str(rows["problem"].iloc[0]) if not rows.empty else "unknown"


def _missing_events(
    kept: pd.DataFrame, tables: dict[str, pd.DataFrame], skip: set[tuple[str, int]]
) -> list[str]:
    notes = []
    for session, event in sorted(skip):
        table = tables.get(session)
        if session in set(kept["session"]) and (table is None or event not in set(table["event"])):
            notes.append(f"study.toml excludes event {event} of {session}, which has no such event")
    return notes


def _removed(
    catalogue: pd.DataFrame,
    study: StudyFile,
    tables: dict[str, pd.DataFrame],
    skip: set[tuple[str, int]],
) -> pd.DataFrame:
    """Every exclusion (the study file's and the automatic ones) and what it removed."""
    rows = []
    out = catalogue[catalogue["excluded"] != ""]
    for session, reason, logged in out[["session", "excluded", "collisions"]].itertuples(
        index=False
    ):
        rows.append((str(session), str(reason), f"1 session ({logged} collisions logged)"))
    for e in study.exclusions:
        if e.event is not None and (e.session, e.event) in skip:
            table = tables.get(e.session)
            hit = table is not None and e.event in set(table["event"])
            rows.append((e.target, e.reason, "1 event" if hit else "nothing (no such event)"))
    return pd.DataFrame(rows, columns=["target", "reason", "removed"])


def _flag_notes(kept: pd.DataFrame) -> list[str]:
    flagged = kept[kept["flags"] != ""]
    return [
        f"kept in the study though flagged: {s} ({f})"
        for s, f in flagged[["session", "flags"]].itertuples(index=False)
    ]
