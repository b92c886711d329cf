"""Analysis of a source and comparison tables across controller runs, in the paper's style.

Events are detected once, on the force of a source's first run (every run of a replay saw the
same input), and shared by all runs, so each run's metrics answer the same collisions. A
comparison lists, per axis, each run's value of each metric and its change against a baseline
run in %, ``100 * (value - baseline) / baseline``, as section 3.4 reports "the maximum offset
increased by 17.46 %". The response time is ``time_to_max_offset_s``, measured from the event's
start, so its change is on time since the collision's onset, as the paper computed its changes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hilrig.analysis.events import DEFAULT_EVENTS, CollisionEvent, EventConfig, detect
from hilrig.analysis.metrics import (
    DEFAULT_METRICS,
    AxisMetrics,
    MetricsConfig,
    TrackingMetrics,
    event_metrics,
    tracking_metrics,
    unit,
)
from hilrig.analysis.sources import Source
from hilrig.analysis.verdict import Verdict, VerdictConfig, area_of, judge, region_of
from hilrig.errors import AnalysisError
from hilrig.robot import RobotModel

# The metrics a comparison lists, in display order; tracking_rms is per run, not per event.
# Peak force and impulse differ between runs only in closed-loop replays (hilrig replay
# --closed-loop, where each run meets its own predicted force); open loop they are equal.
COMPARED = (
    "peak_force",
    "impulse",
    "max_abs_offset",
    "time_to_max_offset_s",
    "recovery_time_s",
    "peak_offset_rate",
    "peak_commanded_joint_speed_rad_s",
    "tracking_rms",
)
DEFAULT_VERDICTS = VerdictConfig()
VERDICT_COLUMNS = tuple(
    f.name for f in dataclasses.fields(Verdict) if f.name not in ("run", "event")
)
PER_EVENT = ("source", "event", "group", "axis")  # one comparison per event and axis
ACROSS_SOURCES = ("group", "axis")  # means over every event of every source, per axis
METRIC_COLUMNS = tuple(
    f.name
    for f in dataclasses.fields(AxisMetrics)
    if f.name not in ("run", "event", "group", "axis", "start_s", "end_s")
)


@dataclass(frozen=True)
class Analysis:
    """A source's events, with every run's metrics per event and axis and its tracking, and
    every run's safety verdict per Cartesian event (none without a body region; ``judged``
    says against what, or why not)."""

    source: Source
    events: tuple[CollisionEvent, ...]
    metrics: tuple[AxisMetrics, ...]
    tracking: tuple[TrackingMetrics, ...]
    verdicts: tuple[Verdict, ...] = ()
    region: str = ""  # the body region judged against ("" none)
    judged: str = ""  # against what (region, where it came from, area), or why not


def analyze(
    source: Source,
    *,
    events: EventConfig = DEFAULT_EVENTS,
    metrics: MetricsConfig = DEFAULT_METRICS,
    safety: VerdictConfig = DEFAULT_VERDICTS,
) -> Analysis:
    """Detect the source's events once, measure every run against them and judge each run's
    Cartesian collisions against the body region's limits."""
    first = source.runs[0]
    found = detect(first.t_s, first.force, first.axes, events)
    region, judged = region_of(safety, source.body_region)
    verdicts: list[Verdict] = []
    if region is not None:
        area = area_of(safety, source.contact_area_cm2)
        model = RobotModel()
        for run in source.runs:
            verdicts += judge(run, found, region, area, safety.transient_s, model)
        judged = f"{region.name} {judged}, contact area {area:.3g} cm^2"
    return Analysis(
        source,
        found,
        tuple(m for run in source.runs for m in event_metrics(run, found, metrics)),
        tuple(m for run in source.runs for m in tracking_metrics(run, found)),
        tuple(verdicts),
        "" if region is None else region.name,
        judged,
    )


def metrics_frame(analyses: Sequence[Analysis]) -> pd.DataFrame:
    """One row per source, run, event and axis: the AxisMetrics fields (None as NaN), the run's
    law, the axis's ``tracking_rms`` over the whole run (the same on each event's row) and the
    run's safety verdict on the event (``VERDICT_COLUMNS``; null without one: a joint event, or
    no body region)."""
    rows = []
    for analysis in analyses:
        laws = {run.name: run.law for run in analysis.source.runs}
        rms = {(t.run, t.axis): t.tracking_rms for t in analysis.tracking}
        judged = {(v.run, v.event): _fields(v) for v in analysis.verdicts}
        for m in analysis.metrics:
            row = _fields(m) | {"group": m.group.value}
            row |= {"source": analysis.source.name, "law": laws[m.run]}
            row |= judged.get((m.run, m.event), {})
            rows.append(row | {"tracking_rms": rms[(m.run, m.axis)]})
    columns = ["source", "run", "law", "event", "group", "axis", "start_s", "end_s"]
    columns += [*METRIC_COLUMNS, "tracking_rms", *VERDICT_COLUMNS]
    texts = ("body_region", "verdict", "binding")
    numeric = {*METRIC_COLUMNS, "tracking_rms", *VERDICT_COLUMNS} - set(texts)
    # column by column, each made with its type (a frame of rows, then astype, took 12 ms for a
    # sweep task's 141 rows, against 1 ms: pandas' per-column overhead)
    data: dict[str, object] = {}
    for column in columns:
        cells = [row.get(column) for row in rows]
        if column in numeric:
            data[column] = np.array(cells, dtype=np.float64)  # None: NaN
        elif column in texts:
            data[column] = pd.Series(cells, dtype=pd.StringDtype())  # None: <NA>
        elif column == "event":
            data[column] = np.array(cells, dtype=np.int64)
        else:  # strings and times, as pandas infers them (nothing: object, as before)
            data[column] = cells if cells else np.array([], dtype=object)
    return pd.DataFrame(data, columns=columns)


def _fields(record: AxisMetrics | Verdict) -> dict[str, object]:
    """A record's fields by name, shallow: ``dataclasses.asdict`` deep-copies every value (0.4 ms
    a row, 5 % of a sweep task's time)."""
    return {name: getattr(record, name) for name in _FIELD_NAMES[type(record)]}


_FIELD_NAMES = {
    kind: tuple(f.name for f in dataclasses.fields(kind)) for kind in (AxisMetrics, Verdict)
}


def values(analyses: Sequence[Analysis]) -> pd.DataFrame:
    """The compared metrics, long: source, run, event (<NA> for per-run tracking), group, axis,
    metric, unit, value (in the metric's SI unit; NaN where a metric has no value)."""
    rows: list[tuple[str, str, int | None, str, str, str, float | None]] = []
    for analysis in analyses:
        name = analysis.source.name
        for m in analysis.metrics:
            for metric in COMPARED[:-1]:
                value = getattr(m, metric)
                rows.append((name, m.run, m.event, m.group.value, m.axis, metric, value))
        for t in analysis.tracking:
            rows.append((name, t.run, None, t.group.value, t.axis, "tracking_rms", t.tracking_rms))
    columns = ["source", "run", "event", "group", "axis", "metric", "value"]
    frame = pd.DataFrame(rows, columns=columns)
    frame["event"] = frame["event"].astype("Int64")
    frame["value"] = frame["value"].astype(np.float64)
    units = {(m, g): unit(m, g) for m, g in frame[["metric", "group"]].itertuples(index=False)}
    frame.insert(6, "unit", [units[k] for k in zip(frame["metric"], frame["group"], strict=True)])
    return frame


def runs_of(long: pd.DataFrame) -> list[str]:
    """The run names of a values table, in first-seen order."""
    return list(dict.fromkeys(long["run"]))


def default_baseline(runs: Sequence[str]) -> str:
    """``fixed`` (the paper's experiment 3) when it is among ``runs``, else the first run."""
    if not runs:
        raise AnalysisError("no controller runs to compare")
    return "fixed" if "fixed" in runs else runs[0]


def comparison(long: pd.DataFrame, *, baseline: str, by: Sequence[str] = PER_EVENT) -> pd.DataFrame:
    """Each run's value of each metric per ``by`` group, with its change against ``baseline``.

    ``long`` is a :func:`values` table. Returns ``by`` + metric, unit, run, value (the mean over
    the group's rows, NaNs skipped), n (values averaged), baseline_value and change_pct (% of the
    baseline; NaN where the baseline has no value or is 0). Rows come by group in first-seen
    order, then metric in COMPARED order, then run, baseline first. Raises AnalysisError if
    ``baseline`` is not a run of ``long``.
    """
    runs = runs_of(long)
    if baseline not in runs:
        raise AnalysisError(f"baseline {baseline!r} is not a run here; runs: {', '.join(runs)}")
    keys = [*by, "metric", "unit", "run"]
    grouped = long.groupby(keys, sort=False, dropna=False)["value"]
    table = grouped.agg(value="mean", n="count").reset_index()
    base = table.loc[table["run"] == baseline, [*by, "metric", "value"]]
    table = table.merge(
        base.rename(columns={"value": "baseline_value"}), on=[*by, "metric"], how="left"
    )
    denominator = table["baseline_value"].where(table["baseline_value"] != 0)
    table["change_pct"] = 100.0 * (table["value"] - denominator) / denominator
    order = {name: i for i, name in enumerate([baseline, *(r for r in runs if r != baseline)])}
    table["_key"] = table.groupby(list(by), sort=False, dropna=False).ngroup()
    table["_metric"] = table["metric"].map({m: i for i, m in enumerate(COMPARED)})
    table["_run"] = table["run"].map(order)
    table = table.sort_values(["_key", "_metric", "_run"], kind="stable")
    return table.drop(columns=["_key", "_metric", "_run"]).reset_index(drop=True)
