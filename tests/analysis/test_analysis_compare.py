"""Comparison tables: the paper's scenario ordering, shared events, and the % change itself."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from analysis_helpers import paper_replay_frame, write_replay

from hilrig.analysis import (
    ACROSS_SOURCES,
    Analysis,
    AxisGroup,
    analyze,
    comparison,
    default_baseline,
    load_replay,
    metrics_frame,
    values,
)
from hilrig.analysis.compare import METRIC_COLUMNS, VERDICT_COLUMNS
from hilrig.control import Law
from hilrig.errors import AnalysisError
from hilrig.paper.experiments import BODY, END_EFFECTOR, peaks, run_experiment

REPORTED = ("x", "y", "z", "joint1", "joint2")


@pytest.fixture(scope="module")
def paper(tmp_path_factory: pytest.TempPathFactory) -> Analysis:
    path = tmp_path_factory.mktemp("replay") / "paper.parquet"
    return analyze(load_replay(write_replay(path, paper_replay_frame())))


def test_replay_tables_are_read_run_by_run_in_order(paper: Analysis) -> None:
    assert [r.name for r in paper.source.runs] == ["adaptive", "variable-stiffness", "fixed"]
    assert paper.source.runs[0].axes == ("x", "y", "z", *(f"joint{j}" for j in range(1, 7)))


def test_the_paper_scenario_has_one_collision_per_group(paper: Analysis) -> None:
    assert [(e.group, round(e.start_s, 3), round(e.end_s, 3)) for e in paper.events] == [
        (AxisGroup.JOINT, 3.52, 5.48),  # tau = 10 t - 35 passes 0.2 N*m after 3.52 s
        (AxisGroup.CARTESIAN, 4.016, 5.982),  # |f| = 13.04 (t - 4) N passes 0.2 N after 4.016 s
    ]


def test_adaptive_beats_variable_stiffness_beats_fixed_on_max_offset(paper: Analysis) -> None:
    table = comparison(values([paper]), baseline="fixed")
    offsets = table[(table["metric"] == "max_abs_offset") & table["axis"].isin(REPORTED)]
    change = offsets.pivot(index="axis", columns="run", values="change_pct")
    assert len(change) == len(REPORTED)
    assert (change["adaptive"] > change["variable-stiffness"]).all()
    assert (change["variable-stiffness"] > 0).all()
    assert (change["fixed"] == 0).all()


def test_metrics_agree_with_the_paper_module_to_the_tick(paper: Analysis) -> None:
    """The same peaks as hilrig.paper, whose times are absolute: event start + response time."""
    ours = {(m.run, m.axis): m for m in paper.metrics}
    for spec in (END_EFFECTOR, BODY):
        for peak in peaks(run_experiment(spec, dt_s=0.002)):
            mine = ours[(peak.law.value, peak.axis.replace(" ", ""))]
            assert mine.max_abs_offset == pytest.approx(peak.max_abs_offset, rel=1e-12)
            assert peak.time_of_max_s is not None
            absolute_s = mine.start_s + mine.time_to_max_offset_s
            assert absolute_s == pytest.approx(peak.time_of_max_s, abs=1e-9)


def test_events_are_shared_by_every_run(paper: Analysis) -> None:
    frame = metrics_frame([paper])
    spans = frame.groupby(["event", "axis"])[["start_s", "end_s", "impulse"]].nunique()
    assert (spans == 1).all().all()
    assert set(frame["run"]) == {law.value for law in Law}


def test_the_metrics_frame_holds_every_record_with_its_values_and_column_types(
    paper: Analysis,
) -> None:
    """One row per metrics record, in order, its fields as they are (None as NaN); numbers
    float64, ``event`` int64, verdict texts pandas strings (<NA> here: no body region); nothing
    analysed gives the same columns."""
    frame = metrics_frame([paper])
    assert len(frame) == len(paper.metrics) > 0
    texts = ("body_region", "verdict", "binding")
    for row, record in zip(frame.itertuples(index=False), paper.metrics, strict=True):
        assert (row.run, row.event, row.axis, row.group) == (
            record.run,
            record.event,
            record.axis,
            record.group.value,
        )
        for column in METRIC_COLUMNS:
            value = getattr(record, column)
            expected = np.nan if value is None else value
            assert getattr(row, column) == pytest.approx(expected, rel=0, abs=0, nan_ok=True)
    numeric = [*METRIC_COLUMNS, "tracking_rms", *(c for c in VERDICT_COLUMNS if c not in texts)]
    assert all(frame[c].dtype == np.float64 for c in numeric)
    assert frame["event"].dtype == np.int64
    assert all(isinstance(frame[c].dtype, pd.StringDtype) for c in texts)
    assert frame[list(texts)].isna().all().all() and frame[numeric[-1]].isna().all()
    empty = metrics_frame([])
    assert list(empty.columns) == list(frame.columns) and empty.empty


def test_response_time_change_is_on_time_since_the_event_start(paper: Analysis) -> None:
    table = comparison(values([paper]), baseline="variable-stiffness")
    row = table[
        (table["metric"] == "time_to_max_offset_s")
        & (table["axis"] == "joint1")
        & (table["run"] == "fixed")
    ].iloc[0]
    ours = {(m.run, m.axis): m.time_to_max_offset_s for m in paper.metrics}
    since_onset = (ours[("fixed", "joint1")], ours[("variable-stiffness", "joint1")])
    assert row["change_pct"] == pytest.approx(100 * (since_onset[0] / since_onset[1] - 1))


def _long(rows: list[tuple[str, int, str, float]]) -> pd.DataFrame:
    frame = pd.DataFrame(rows, columns=["run", "event", "axis", "value"])
    return frame.assign(source="s", group="cartesian", metric="max_abs_offset", unit="m")


def test_change_is_value_minus_baseline_over_baseline_in_percent() -> None:
    long = _long([("fixed", 0, "x", 2.0), ("adaptive", 0, "x", 3.0), ("fast", 0, "x", 1.0)])
    table = comparison(long, baseline="fixed")
    assert list(table["run"]) == ["fixed", "adaptive", "fast"]
    assert list(table["change_pct"]) == [0.0, 50.0, -50.0]
    assert list(table["baseline_value"]) == [2.0, 2.0, 2.0]


def test_no_change_against_a_zero_or_missing_baseline() -> None:
    long = _long([("fixed", 0, "x", 0.0), ("adaptive", 0, "x", 1.0), ("adaptive", 0, "y", 1.0)])
    table = comparison(long, baseline="fixed")
    assert table["change_pct"].isna().tolist() == [True, True, True]


def test_across_sources_means_every_event_per_axis() -> None:
    long = _long(
        [
            ("fixed", 0, "x", 1.0),
            ("fixed", 1, "x", 3.0),
            ("adaptive", 0, "x", 4.0),
            ("adaptive", 3, "x", np.nan),  # no value: skipped
        ]
    )
    table = comparison(long, baseline="fixed", by=ACROSS_SOURCES)
    assert table[["run", "value", "n", "change_pct"]].values.tolist() == [
        ["fixed", 2.0, 2, 0.0],
        ["adaptive", 4.0, 1, 100.0],
    ]


def test_the_default_baseline_is_fixed_else_the_first_run() -> None:
    assert default_baseline(["adaptive", "fixed"]) == "fixed"
    assert default_baseline(["adaptive.a1=10", "adaptive"]) == "adaptive.a1=10"
    with pytest.raises(AnalysisError):
        default_baseline([])


def test_an_unknown_baseline_is_refused_naming_the_runs() -> None:
    with pytest.raises(AnalysisError, match="'stiff' is not a run here; runs: fixed"):
        comparison(_long([("fixed", 0, "x", 1.0)]), baseline="stiff")


def test_a_table_that_breaks_the_replay_contract_is_refused(tmp_path: Path) -> None:
    frame = paper_replay_frame(laws=("fixed",), duration_s=1.0).drop(columns=["velocity_y"])
    path = write_replay(tmp_path / "broken.parquet", frame)
    with pytest.raises(AnalysisError, match=r"broken.parquet: not a replay table.*velocity_y"):
        load_replay(path)


def test_an_empty_replay_table_is_refused(tmp_path: Path) -> None:
    frame = paper_replay_frame(laws=("fixed",), duration_s=1.0).iloc[:0]
    with pytest.raises(AnalysisError, match=r"empty\.parquet: a replay table without rows"):
        load_replay(write_replay(tmp_path / "empty.parquet", frame))
