"""Tables for the statistics tests (tests/study/test_stats*.py)."""

from __future__ import annotations

import pandas as pd

from hilrig.study.records import OBSERVATION_COLUMNS, SUBJECT_COLUMNS


def values_table(
    samples: dict[str, dict[str, float]], metric: str = "peak_force", group: str = "cartesian"
) -> pd.DataFrame:
    """A subject-values table: {condition: {subject: value}}, one event each."""
    rows = [
        (subject, condition, group, metric, float(value), 1)
        for condition, by_subject in samples.items()
        for subject, value in by_subject.items()
    ]
    return pd.DataFrame(rows, columns=list(SUBJECT_COLUMNS))


def observations_of(rows: list[tuple[str, str, int, str, float]]) -> pd.DataFrame:
    """Observations from (subject, condition, event, metric, value); one session per subject
    and condition, group cartesian, axis z."""
    full = [(f"{s}-{c}", s, c, e, "cartesian", "z", m, v) for s, c, e, m, v in rows]
    return pd.DataFrame(full, columns=list(OBSERVATION_COLUMNS))


def only_row(table: pd.DataFrame) -> pd.Series:
    assert len(table) == 1
    return table.iloc[0]
