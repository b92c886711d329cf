"""``hilrig sweep``'s closing tables: each parameter set's collisions across subjects, one table
per axis group (:mod:`hilrig.sweep.summary`), or with many parameter sets the lowest and the
highest of each metric."""

from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from rich.markup import escape
from rich.table import Table

from hilrig.analysis.report import shown
from hilrig.study.records import STUDY_METRICS, metric_heading, metric_unit

#: Parameter sets shown row by row; with more, each metric's lowest and highest run.
MAX_ROWS = 20
HOW = "median over subjects of each subject's mean; each event on its loaded axis"


def summary_tables(by_run: pd.DataFrame) -> list[Table]:
    """The tables of a sweep's summary (:data:`hilrig.sweep.summary.SUMMARY_COLUMNS`), one
    per axis group; a metric without a value in a group (the margin on joints) is left out."""
    tables = []
    for group, rows in by_run.groupby("group", sort=True):
        rows = rows.reset_index(drop=True)
        metrics = [m for m in STUDY_METRICS if rows[m].notna().any()]
        judged = bool(rows["judged"].sum())
        if len(rows) <= MAX_ROWS:
            tables.append(_by_run(str(group), rows, metrics, judged))
        else:
            tables.append(_extremes(str(group), rows, metrics, judged))
    return tables


def _by_run(group: str, rows: pd.DataFrame, metrics: list[str], judged: bool) -> Table:
    """One row per run. A narrow terminal folds the numbers and headings onto more lines;
    the run's name is never cut."""
    table = Table(title=f"{group} collisions per parameter set ({HOW})", title_justify="left")
    longest = max(len(str(run)) for run in rows["run"])
    table.add_column("run", no_wrap=True, min_width=longest)
    for head in ["subjects", "events", *(["ISO over"] if judged else [])]:
        table.add_column(head, justify="right", overflow="fold")
    for metric in metrics:
        table.add_column(metric_heading(metric, group, "\n"), justify="right", overflow="fold")
    for i in range(len(rows)):
        row = rows.iloc[i]
        cells = [escape(str(row["run"])), str(row["subjects"]), str(row["events"])]
        if judged:
            cells.append(f"{row['over']} of {row['judged']}")
        cells += [shown(float(row[m]), metric_unit(m, group)) for m in metrics]
        table.add_row(*cells)
    return table


def _extremes(group: str, rows: pd.DataFrame, metrics: list[str], judged: bool) -> Table:
    title = (
        f"{group} collisions over {len(rows)} parameter sets ({HOW}): each metric's lowest and "
        "highest (every row: hilrig.sweep.summarise(OUT))"
    )
    table = Table(title=title, title_justify="left")
    for head in ("metric", "lowest", "run", "highest", "run"):
        table.add_column(head, justify="right" if head in ("lowest", "highest") else "left")
    runs = [escape(str(run)) for run in rows["run"]]
    if judged:
        over = rows["over"].to_numpy(np.float64)
        table.add_row("events over ISO/TS 15066", *_span(over, runs, None))
    for metric in metrics:
        si_unit = metric_unit(metric, group)
        values = rows[metric].to_numpy(np.float64)
        table.add_row(metric_heading(metric, group), *_span(values, runs, si_unit))
    return table


def _span(values: NDArray[np.float64], runs: list[str], si_unit: str | None) -> list[str]:
    """Lowest value, its run, highest value, its run (the first of equals; NaN skipped; a
    count where ``si_unit`` is None); "every run" when all are equal."""
    low, high = int(np.nanargmin(values)), int(np.nanargmax(values))
    low_text, high_text = (
        f"{values[i]:.0f}" if si_unit is None else shown(float(values[i]), si_unit)
        for i in (low, high)
    )
    if values[low] == values[high]:
        return [low_text, "every run", high_text, "every run"]
    return [low_text, runs[low], high_text, runs[high]]
