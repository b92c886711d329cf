"""The records a study passes between its parts: column sets of its tables, the metrics it
compares, an exclusion, a representative event's curves and everything a report shows.

Tables are pandas DataFrames with exactly the columns named here, in this order:

- observations (:data:`OBSERVATION_COLUMNS`): one row per session, event and metric, the value
  on the event's loaded axis (the axis with the largest |peak force|), in the metric's SI unit
  (:func:`metric_unit`); peak force and impulse as magnitudes.
- subject values (:data:`SUBJECT_COLUMNS`): per subject, condition, group and metric the mean
  over that subject's events (every repetition) and how many there were.
- distributions (:data:`DISTRIBUTION_COLUMNS`): per condition, group and metric the
  distribution of the subject values.
- comparisons (:data:`COMPARISON_COLUMNS`): each condition against the baseline per group and
  metric (docs/study.md, "Statistics").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.analysis.metrics import unit
from hilrig.analysis.report import shown_unit

FloatArray = NDArray[np.float64]

#: The metrics a study compares, in display order (per event, except tracking_rms: per run).
STUDY_METRICS = (
    "peak_force",
    "impulse",
    "max_abs_offset",
    "time_to_max_offset_s",
    "recovery_time_s",
    "tracking_rms",
    "margin_pct",
)
#: What each metric is, for tables and figures.
METRIC_LABELS = {
    "peak_force": "peak force",
    "impulse": "impulse",
    "max_abs_offset": "maximum offset",
    "time_to_max_offset_s": "response time",
    "recovery_time_s": "recovery time",
    "tracking_rms": "tracking RMS",
    "margin_pct": "ISO/TS 15066 margin",
}

OBSERVATION_COLUMNS = (
    "session",  # session id
    "subject",  # pseudonymous subject id
    "condition",  # controller (with its parameters where one controller ran with several)
    "event",  # the event's number in its session (0, 1, ...)
    "group",  # "cartesian" or "joint"
    "axis",  # the loaded axis: x, y, z or joint1..joint6
    "metric",  # one of STUDY_METRICS
    "value",  # float, NaN where the metric has no value (e.g. no recovery)
)
SUBJECT_COLUMNS = ("subject", "condition", "group", "metric", "value", "events")
DISTRIBUTION_COLUMNS = (
    "group",
    "metric",
    "condition",
    "subjects",  # subjects with a value
    "events",  # events behind them
    "median",
    "q1",
    "q3",
    "mean",
    "sd",  # sample standard deviation (ddof=1); NaN for one subject
    "min",
    "max",
)
COMPARISON_COLUMNS = (
    "group",
    "metric",
    "condition",
    "baseline",
    "design",  # "paired" (subjects who saw both) or "unpaired"
    "n_baseline",  # subjects in the baseline's sample
    "n_condition",  # subjects in the condition's sample (= n_baseline when paired)
    "left_out",  # subjects who saw only one of the two (paired design), else 0
    "median_baseline",
    "median_condition",
    "median_difference",  # paired: median of condition - baseline; unpaired: of the medians
    "ci_low",  # bootstrap confidence interval of median_difference
    "ci_high",
    "test",  # "wilcoxon" or "mann-whitney"
    "statistic",
    "p_value",
    "p_adjusted",  # Benjamini-Hochberg over every row of the table
    "effect_size",  # rank-biserial correlation, -1..1 (positive: condition larger)
)


def metric_unit(metric: str, group: str) -> str:
    """The unit of a study metric on an axis of ``group`` ("%" for the safety margin)."""
    return "%" if metric == "margin_pct" else unit(metric, group)


def shown_metric_unit(metric: str, group: str) -> tuple[str, float]:
    """The unit a study metric on ``group``'s axes is shown in and the factor to it (mm)."""
    return shown_unit(metric_unit(metric, group))


def metric_heading(metric: str, group: str, sep: str = " ") -> str:
    """A study metric's label and shown unit: "maximum offset (mm)" (``sep`` between)."""
    unit_shown, _ = shown_metric_unit(metric, group)
    return f"{METRIC_LABELS.get(metric, metric)}{sep}({unit_shown})"


@dataclass(frozen=True)
class Exclusion:
    """A session (``event`` None) or one of its events left out of the study, and why."""

    session: str
    reason: str
    event: int | None = None

    @property
    def target(self) -> str:
        """``SESSION`` or ``SESSION#EVENT``, as the command line and the report write it."""
        return self.session if self.event is None else f"{self.session}#{self.event}"


@dataclass(frozen=True)
class EventCurve:
    """A representative event of a condition: the loaded axis from ``t_s`` -0.2 s before the
    event's start (t_s = 0) to the end of its recovery window, with the controller's state."""

    condition: str
    subject: str
    session: str
    event: int
    group: str
    axis: str
    t_s: FloatArray
    force: FloatArray  # N or N*m
    offset: FloatArray  # m or rad
    damping: FloatArray  # N*s/m or N*m*s/rad
    stiffness: FloatArray  # N/m or N*m/rad
    zeta: FloatArray  # damping ratio


@dataclass(frozen=True)
class StudyReport:
    """Everything the report shows (docs/study.md, "The report")."""

    name: str  # the study's name (study.toml), else its folder's name
    created_utc: str  # ISO 8601
    software_version: str
    command: str  # the command line that reproduces the report
    baseline: str  # the condition the others are compared against
    catalogue: pd.DataFrame  # hilrig.study.catalogue.CATALOGUE_COLUMNS, every session found
    exclusions: pd.DataFrame  # target, reason, what it removed (sessions and events)
    design: pd.DataFrame  # condition, subjects, sessions, events (after exclusions)
    design_text: tuple[str, ...]  # who saw what, one sentence each
    observations: pd.DataFrame
    subject_values: pd.DataFrame
    distributions: pd.DataFrame
    comparisons: pd.DataFrame
    curves: tuple[EventCurve, ...] = ()
    notes: tuple[str, ...] = field(default_factory=tuple)  # quality warnings, one line each
