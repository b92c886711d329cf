"""A sweep's summary: each parameter set's collisions across subjects, summarised as a study
summarises its conditions (docs/sweeps.md, "The summary").

Each event counts once, on its loaded axis (the study's rule,
:func:`hilrig.study.observations.loaded_events`); a subject's value of a metric under a run is
the mean over that subject's events in every source of the sweep (NaN skipped), and the run's
value is the median over its subjects, so a subject with many sessions weighs no more than one
with few. A source without a subject id is a subject of its own.

A task reduces its metrics to a :class:`GroupTally` per group (events, verdicts, per-metric
sums and counts), a few numbers that travel back with its result; :class:`Tally` adds them up
per subject and run, so a sweep of any size is summarised without reading its metrics again.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from hilrig.errors import SweepError
from hilrig.study.observations import loaded_events
from hilrig.study.records import STUDY_METRICS
from hilrig.sweep.dataset import read_sweep

#: One row per run and group, runs in the order given: subjects and events behind the values,
#: the events with an ISO/TS 15066 verdict and those over a limit, then per study metric the
#: median over subjects of each subject's mean (peak force and impulse as magnitudes).
SUMMARY_COLUMNS = ("run", "group", "subjects", "events", "judged", "over", *STUDY_METRICS)
#: One row per run, group and subject: the subject's events and its mean of each study metric
#: (the values whose median over subjects is the summary's).
SUBJECT_COLUMNS = ("run", "group", "subject", "events", *STUDY_METRICS)
#: The metrics columns a summary reads.
READ_COLUMNS = ("subject_id", "event", "group", "verdict", *STUDY_METRICS)


@dataclass(frozen=True)
class GroupTally:
    """One task's events of one group: how many, how many judged and over an ISO/TS 15066
    limit, and per study metric (:data:`STUDY_METRICS` order) the sum and count of the
    loaded-axis values (NaN left out)."""

    group: str
    events: int
    judged: int
    over: int
    sums: tuple[float, ...]
    counts: tuple[int, ...]


def tally(metrics: pd.DataFrame) -> tuple[GroupTally, ...]:
    """A task's metrics rows (one source, one run) reduced to one tally per group."""
    if metrics.empty:
        return ()
    events = loaded_events(metrics)
    groups = events["group"].to_numpy(dtype=object)
    values = events.loc[:, list(STUDY_METRICS)].to_numpy(np.float64)
    judged = events["verdict"].notna().to_numpy(dtype=bool)
    over = (events["verdict"] == "over").fillna(False).to_numpy(dtype=bool)
    out = []
    for group in sorted(set(groups)):
        rows = groups == group
        part = values[rows]
        with np.errstate(invalid="ignore"):  # inf - inf: NaN, as pandas' mean gives it
            sums = np.nansum(part, axis=0)
        out.append(
            GroupTally(
                str(group),
                int(rows.sum()),
                int(judged[rows].sum()),
                int(over[rows].sum()),
                tuple(float(v) for v in sums),
                tuple(int(n) for n in (~np.isnan(part)).sum(axis=0)),
            )
        )
    return tuple(out)


def subject_of(metrics: pd.DataFrame, source: str) -> str:
    """The task's subject: its metrics' subject id, else the source itself."""
    if not metrics.empty:
        subject = metrics["subject_id"].iloc[0]
        if isinstance(subject, str) and subject:
            return subject
    return source


def read_tally(path: Path, source: str) -> tuple[str, tuple[GroupTally, ...]]:
    """The subject and tallies of a metrics partition already written (a task done before).
    Raises SweepError if it cannot be read."""
    try:
        metrics = pq.read_table(path, columns=list(READ_COLUMNS)).to_pandas()
    except (OSError, pa.ArrowException) as err:
        raise SweepError(
            f"{path}: cannot read the task's metrics ({err}); delete it and run the sweep again "
            "to redo that task"
        ) from err
    return subject_of(metrics, source), tally(metrics)


class Tally:
    """Tasks' tallies kept per (run, group, subject) and source; :meth:`table` is the summary."""

    def __init__(self, runs: Sequence[str]) -> None:
        self._order = {run: i for i, run in enumerate(runs)}
        self._cells: dict[tuple[str, str, str], dict[str, GroupTally]] = {}

    def __contains__(self, run: object) -> bool:
        return run in self._order

    def add(self, run: str, source: str, subject: str, tallies: Iterable[GroupTally]) -> None:
        """Add a task's tallies (again: they replace its earlier ones); ``run`` must be one of
        the runs given."""
        if run not in self._order:
            raise ValueError(f"run {run!r} is not one of the summary's")
        for part in tallies:
            self._cells.setdefault((run, part.group, subject), {})[source] = part

    def table(self) -> pd.DataFrame:
        """The summary (:data:`SUMMARY_COLUMNS`): rows by run (as given), then group."""
        by_run: dict[tuple[str, str], list[_Cell]] = {}
        for (run, group, _), sources in self._cells.items():
            by_run.setdefault((run, group), []).append(_Cell(sources))
        rows = []
        for (run, group), cells in sorted(by_run.items(), key=self._row_order):
            means = np.array([cell.means() for cell in cells])
            rows.append(
                {
                    "run": run,
                    "group": group,
                    "subjects": len(cells),
                    "events": sum(c.events for c in cells),
                    "judged": sum(c.judged for c in cells),
                    "over": sum(c.over for c in cells),
                }
                | {m: _median(means[:, i]) for i, m in enumerate(STUDY_METRICS)}
            )
        table = pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))
        counts = ("subjects", "events", "judged", "over")
        return table.astype(dict.fromkeys(counts, np.int64) | dict.fromkeys(STUDY_METRICS, float))

    def by_subject(self) -> pd.DataFrame:
        """Each subject's values (:data:`SUBJECT_COLUMNS`): rows by run (as given), group, then
        subject."""
        keys = sorted(self._cells, key=lambda key: (self._order[key[0]], key[1], key[2]))
        rows = []
        for run, group, subject in keys:
            cell = _Cell(self._cells[run, group, subject])
            head = {"run": run, "group": group, "subject": subject, "events": cell.events}
            rows.append(head | dict(zip(STUDY_METRICS, cell.means(), strict=True)))
        table = pd.DataFrame(rows, columns=list(SUBJECT_COLUMNS))
        return table.astype({"events": np.int64} | dict.fromkeys(STUDY_METRICS, float))

    def _row_order(self, item: tuple[tuple[str, str], object]) -> tuple[int, str]:
        (run, group), _ = item
        return self._order[run], group


def summarise(root: Path, runs: Sequence[str] | None = None) -> pd.DataFrame:
    """The summary of the sweep in ``root``: every run (by controller, then its settings'
    values: ``a1=5`` before ``a1=10``), or ``runs`` in that order. Raises SweepError if it
    holds no metrics or they cannot be read."""
    metrics = read_sweep(root, columns=["source", "run", "controller", "settings", *READ_COLUMNS])
    names = _in_order(metrics) if runs is None else list(runs)
    summary = Tally(names)
    for (source, run), part in metrics.groupby(["source", "run"], sort=False):
        if run in summary:
            summary.add(str(run), str(source), subject_of(part, str(source)), tally(part))
    return summary.table()


def _in_order(metrics: pd.DataFrame) -> list[str]:
    """The runs of ``metrics``, by controller and then by their settings' values."""
    runs = metrics.drop_duplicates("run")
    keys: dict[str, tuple[str, list[tuple[str, tuple[int, float, str]]]]] = {}
    for run, controller, settings in runs[["run", "controller", "settings"]].itertuples(
        index=False
    ):
        values = json.loads(str(settings))
        keys[str(run)] = (str(controller), [(k, _sort_key(values[k])) for k in sorted(values)])
    return sorted(keys, key=lambda run: (keys[run], run))


def _sort_key(value: object) -> tuple[int, float, str]:
    """Numbers by value, before anything else (by its text)."""
    if isinstance(value, int | float):
        return 0, float(value), ""
    return 1, 0.0, json.dumps(value)


class _Cell:
    """One subject's events under one run and group: its sources' tallies added up in source
    order (the same sums however the tasks came back)."""

    def __init__(self, sources: dict[str, GroupTally]) -> None:
        parts = [sources[name] for name in sorted(sources)]
        self.events = sum(p.events for p in parts)
        self.judged = sum(p.judged for p in parts)
        self.over = sum(p.over for p in parts)
        self.sums = np.zeros(len(STUDY_METRICS))
        self.counts = np.zeros(len(STUDY_METRICS), dtype=np.int64)
        with np.errstate(invalid="ignore"):
            for part in parts:
                self.sums += part.sums
                self.counts += part.counts

    def means(self) -> NDArray[np.float64]:
        with np.errstate(all="ignore"):
            return np.where(self.counts > 0, self.sums / np.maximum(self.counts, 1), np.nan)


def _median(values: NDArray[np.float64]) -> float:
    """The median of the values that are not NaN (subjects without a value); NaN if none."""
    kept = values[~np.isnan(values)]
    if not len(kept):
        return float("nan")
    with np.errstate(invalid="ignore"):  # the middle of -inf and inf: NaN
        return float(np.median(kept))
