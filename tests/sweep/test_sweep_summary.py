"""A sweep's summary: each run's collisions across subjects, against an independent oracle
(loaded axis by argmax, subject means and medians by numpy), the same however the tasks come
back, the same after a rerun, and shown by ``hilrig sweep``."""

from __future__ import annotations

import random
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console
from sweep_helpers import SWEEP, force_table, hilrig, sessions

from hilrig.cli import sweep_table
from hilrig.errors import SweepError
from hilrig.replay import parse_specs
from hilrig.study.observations import loaded_events
from hilrig.study.records import STUDY_METRICS
from hilrig.sweep import METRICS, Layout, find_inputs, plan, read_sweep, summarise
from hilrig.sweep import sweep as run_sweep
from hilrig.sweep.summary import SUMMARY_COLUMNS, Tally, subject_of, tally

SPECS = parse_specs(["adaptive"], sweeps=["adaptive.a1=5,10,20"])
AXES = {"cartesian": ("x", "y", "z"), "joint": tuple(f"joint{j}" for j in range(1, 7))}


def oracle(metrics: pd.DataFrame, runs: list[str]) -> pd.DataFrame:
    """The summary computed another way: a loop per event, numpy's nanmean and median."""
    events = []
    for (source, run, _), rows in metrics.groupby(["source", "run", "event"], sort=False):
        row = rows.iloc[int(np.argmax(np.abs(rows["peak_force"].to_numpy())))]
        subject = row["subject_id"] if isinstance(row["subject_id"], str) else source
        values = {m: float(row[m]) for m in STUDY_METRICS}
        values["peak_force"], values["impulse"] = abs(values["peak_force"]), abs(values["impulse"])
        verdict = row["verdict"] if isinstance(row["verdict"], str) else None
        events.append({"run": run, "group": row["group"], "subject": subject, "verdict": verdict}
                      | values)  # fmt: skip
    table = pd.DataFrame(events)
    out = []
    for run in runs:
        for group in sorted(set(table.loc[table["run"] == run, "group"])):
            part = table[(table["run"] == run) & (table["group"] == group)]
            by_subject = [p for _, p in part.groupby("subject")]
            medians = {}
            for m in STUDY_METRICS:
                with warnings.catch_warnings():  # an all-NaN subject, inf - inf
                    warnings.simplefilter("ignore", RuntimeWarning)
                    means = np.array([np.nanmean(p[m].to_numpy(float)) for p in by_subject])
                    kept = means[~np.isnan(means)]
                    medians[m] = float(np.median(kept)) if len(kept) else np.nan
            verdicts = part["verdict"]
            out.append(
                {
                    "run": run,
                    "group": group,
                    "subjects": len(by_subject),
                    "events": len(part),
                    "judged": int(verdicts.notna().sum()),
                    "over": int((verdicts == "over").sum()),
                }
                | medians
            )
    return pd.DataFrame(out, columns=list(SUMMARY_COLUMNS))


def summary_by_tally(metrics: pd.DataFrame, runs: list[str], *, seed: int = 0) -> pd.DataFrame:
    parts = list(metrics.groupby(["source", "run"], sort=False))
    random.Random(seed).shuffle(parts)
    summary = Tally(runs)
    for (source, run), part in parts:
        summary.add(str(run), str(source), subject_of(part, str(source)), tally(part))
    return summary.table()


def assert_same(got: pd.DataFrame, expected: pd.DataFrame) -> None:
    assert got[list(SUMMARY_COLUMNS[:6])].to_dict("records") == (
        expected[list(SUMMARY_COLUMNS[:6])].to_dict("records")
    )
    np.testing.assert_allclose(
        got[list(STUDY_METRICS)].to_numpy(float),
        expected[list(STUDY_METRICS)].to_numpy(float),
        rtol=1e-12,
        equal_nan=True,
    )


values = st.one_of(st.floats(-50, 50, allow_nan=False), st.sampled_from([np.nan, np.inf, -np.inf]))


@st.composite
def metrics_rows(draw: st.DrawFn) -> pd.DataFrame:
    """Metrics rows of random tasks: 1-4 sources of 1-3 subjects (or none), 1-2 runs, 0-3
    events each, peak forces with ties, NaN values and verdicts on Cartesian events."""
    sources = [f"s{i}" for i in range(draw(st.integers(1, 4)))]
    subjects = {s: draw(st.sampled_from(["A", "B", "C", None])) for s in sources}
    rows = []
    for run in ["r1", "r2"][: draw(st.integers(1, 2))]:
        for source in sources:
            for event in range(draw(st.integers(0, 3))):
                group = draw(st.sampled_from(sorted(AXES)))
                verdict = (
                    draw(st.sampled_from(["within", "over"])) if group == "cartesian" else None
                )
                for axis in AXES[group]:
                    row = {m: draw(values) for m in STUDY_METRICS}
                    row["peak_force"] = draw(st.sampled_from([-3.0, 3.0, 1.5, 0.0]))
                    rows.append({"source": source, "run": run, "event": event, "group": group,
                                 "axis": axis, "verdict": verdict,
                                 "subject_id": subjects[source]} | row)  # fmt: skip
    frame = pd.DataFrame(rows, columns=["source", "run", "event", "group", "axis", "verdict",
                                        "subject_id", *STUDY_METRICS])  # fmt: skip
    return frame.astype({"event": np.int64} | dict.fromkeys(STUDY_METRICS, float))


@settings(max_examples=150, deadline=None)
@given(metrics_rows(), st.integers(0, 1000))
def test_the_summary_is_the_oracle_s_in_any_order_of_tasks(
    metrics: pd.DataFrame, seed: int
) -> None:
    runs = ["r1", "r2"]
    runs = [r for r in runs if r in set(metrics["run"])] or runs[:1]
    got = summary_by_tally(metrics, runs, seed=seed)
    assert_same(got, oracle(metrics, runs) if not metrics.empty else got.iloc[0:0])
    pd.testing.assert_frame_equal(got, summary_by_tally(metrics, runs, seed=seed + 1))


@settings(max_examples=100, deadline=None)
@given(metrics_rows())
def test_loaded_events_keep_the_first_largest_peak_of_each_event(metrics: pd.DataFrame) -> None:
    got = loaded_events(metrics, by=["source", "run"])
    expected = []
    for _, rows in metrics.groupby(["source", "run", "event"], sort=True):
        expected.append(rows.index[int(np.argmax(np.abs(rows["peak_force"].to_numpy())))])
    assert list(got.index) == expected
    assert (got["peak_force"] == metrics.loc[expected, "peak_force"].abs()).all()
    assert got["impulse"].equals(metrics.loc[expected, "impulse"].abs())


def test_tally_refuses_a_run_it_was_not_given() -> None:
    with pytest.raises(ValueError, match="run 'r9' is not one of the summary's"):
        Tally(["r1"]).add("r9", "s0", "A", ())


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pd.DataFrame]:
    """Two recorded sessions of one subject, one of another, and a force table (a subject of
    its own), swept through three parameter sets."""
    root = tmp_path_factory.mktemp("summary")
    sessions(root / "in" / "a", count=2, duration_s=6.0)
    sessions(root / "in" / "b", count=1, duration_s=9.0)
    force_table(root / "in" / "push.parquet", 22.0)
    tasks = plan(find_inputs([root / "in"]), SPECS, closed_loop=False)
    summary = run_sweep(tasks, root / "out")
    return root, summary.by_run


def test_a_sweep_s_summary_is_the_oracle_s_on_its_metrics(swept: tuple[Path, pd.DataFrame]) -> None:
    root, by_run = swept
    runs = [spec.name for spec in SPECS]
    metrics = read_sweep(root / "out")
    assert set(metrics["subject_id"].dropna()) == {"S001", "S002"}
    assert list(by_run["run"].drop_duplicates()) == runs  # as the sweep declared them
    assert set(by_run["subjects"]) <= {1, 2, 3} and (by_run["events"] > 0).all()
    assert_same(by_run, oracle(metrics, runs))
    pd.testing.assert_frame_equal(by_run, summarise(root / "out"))  # a1=5 before a1=10


def test_a_rerun_reads_the_tasks_done_before_into_the_same_summary(
    swept: tuple[Path, pd.DataFrame], tmp_path: Path
) -> None:
    root, by_run = swept
    tasks = plan(find_inputs([root / "in"]), SPECS, closed_loop=False)
    again = run_sweep(tasks, root / "out")
    assert (again.already_done, len(again.results)) == (len(tasks), 0)
    pd.testing.assert_frame_equal(again.by_run, by_run)
    partial = tmp_path / "out"
    shutil.copytree(root / "out", partial)
    Layout(partial).partition(METRICS, tasks[4].source, tasks[4].run).unlink()
    resumed = run_sweep(tasks, partial)
    assert (resumed.already_done, len(resumed.results)) == (len(tasks) - 1, 1)
    pd.testing.assert_frame_equal(resumed.by_run, by_run)


def test_an_unreadable_old_partition_is_one_line_after_the_new_work(
    swept: tuple[Path, pd.DataFrame], tmp_path: Path
) -> None:
    root, _ = swept
    broken = tmp_path / "out"
    shutil.copytree(root / "out", broken)
    tasks = plan(find_inputs([root / "in"]), SPECS, closed_loop=False)
    path = Layout(broken).partition(METRICS, tasks[0].source, tasks[0].run)
    path.write_bytes(b"not parquet")
    owed = Layout(broken).partition(METRICS, tasks[1].source, tasks[1].run)
    owed.unlink()
    with pytest.raises(SweepError) as err:
        run_sweep(tasks, broken)
    assert owed.is_file()  # the task still to do was done first
    message = str(err.value)
    assert message.startswith(f"{path}: cannot read the task's metrics (")
    assert message.endswith("); delete it and run the sweep again to redo that task")
    assert "\n" not in message
    path.unlink()
    redone = run_sweep(tasks, broken)
    assert [(r.source, r.run) for r in redone.results] == [(tasks[0].source, tasks[0].run)]
    pd.testing.assert_frame_equal(redone.by_run, swept[1])


def test_hilrig_sweep_ends_with_each_group_s_table_of_runs(tmp_path: Path) -> None:
    sessions(tmp_path / "in", count=2)
    out = tmp_path / "out"
    done = hilrig("sweep", str(tmp_path / "in"), *SWEEP, "-o", str(out), columns=300)
    assert done.returncode == 0, done.stderr
    by_run = summarise(out)
    sections = {}
    for group in ("cartesian", "joint"):
        title = f"{group} collisions per parameter set (median over subjects of each subject's"
        _, found, after = done.stdout.partition(title)
        assert found, done.stdout
        sections[group] = after.split(" collisions per parameter set")[0].splitlines()
    for row in by_run.itertuples(index=False):
        line = next(x for x in sections[str(row.group)] if x.startswith(f"│ {row.run} "))
        cells = [cell.strip() for cell in line.split("│")[1:-1]]
        shown = [str(row.run), str(row.subjects), str(row.events)]
        if row.judged:
            shown.append(f"{row.over} of {row.judged}")
        assert cells[: len(shown) + 1] == [*shown, f"{row.peak_force:.4g}"]


def test_many_runs_are_shown_by_each_metric_s_lowest_and_highest(
    swept: tuple[Path, pd.DataFrame], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, by_run = swept
    monkeypatch.setattr(sweep_table, "MAX_ROWS", 2)
    console = Console(width=300, record=True)
    for table in sweep_table.summary_tables(by_run):
        console.print(table)
    text = console.export_text()
    cartesian = by_run[by_run["group"] == "cartesian"].reset_index(drop=True)
    offset = cartesian["max_abs_offset"]
    runs = list(cartesian["run"])
    low, high = runs[int(offset.to_numpy().argmin())], runs[int(offset.to_numpy().argmax())]
    assert low != high
    line = next(x for x in text.splitlines() if x.startswith("│ maximum offset (mm)"))
    assert [c.strip() for c in line.split("│")[2:6]] == [
        f"{offset.min() * 1000:.4g}",
        low,
        f"{offset.max() * 1000:.4g}",
        high,
    ]
    line = next(x for x in text.splitlines() if x.startswith("│ peak force (N) "))
    assert [c.strip() for c in line.split("│")[3:6:2]] == ["every run", "every run"]  # open loop


def test_a_sweep_without_collisions_says_so(tmp_path: Path) -> None:
    quiet = tmp_path / "quiet.parquet"
    pd.DataFrame({"t": np.arange(3000) / 1000, "fx": 0.0, "fy": 0.0, "fz": 0.0}).to_parquet(quiet)
    done = hilrig("sweep", str(quiet), *SWEEP, "-o", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[1:] == ["no collisions in any source: no summary"]
    by_run = summarise(tmp_path / "out")
    assert by_run.empty and tuple(by_run.columns) == SUMMARY_COLUMNS


def test_a_narrow_terminal_folds_numbers_and_never_cuts_a_run_s_name(
    swept: tuple[Path, pd.DataFrame],
) -> None:
    _, by_run = swept
    console = Console(width=80, record=True)
    for table in sweep_table.summary_tables(by_run):
        console.print(table)
    text = console.export_text()
    assert "…" not in text
    lines = text.splitlines()
    for run in by_run["run"]:
        assert sum(line.startswith(f"│ {run} ") for line in lines) == 2  # once in each group
