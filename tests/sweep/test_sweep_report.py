"""A sweep's HTML report: the subjects' values behind the summary, the figure's layout of the
runs, and the file in Debian's headless chromium; ``hilrig sweep --report`` end to end."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import matplotlib as mpl
import numpy as np
import pandas as pd
import pytest
from sweep_helpers import force_table, hilrig

from hilrig.errors import OutputError
from hilrig.replay import parse_specs
from hilrig.replay.specs import ControllerSpec
from hilrig.study.figures import RC
from hilrig.study.records import STUDY_METRICS
from hilrig.study.report_html import number
from hilrig.sweep import SweepSummary, find_inputs, plan
from hilrig.sweep import sweep as run_sweep
from hilrig.sweep.report import check_report, write_sweep_report
from hilrig.sweep.report_figures import draw, layout, quartiles, with_over

sys.path.insert(0, str(Path(__file__).parents[1] / "study"))
from browser import LoadedPage, open_page

SPECS = parse_specs(["adaptive", "fixed"], sweeps=["adaptive.a1=5,10,20"])
SWEEP = ("-c", "adaptive", "-c", "fixed", "--sweep", "adaptive.a1=5,10,20")


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> tuple[SweepSummary, Path]:
    """Three force tables (a subject each) through four runs, and the sweep's report."""
    root = tmp_path_factory.mktemp("report")
    (root / "in").mkdir()
    tables = [
        force_table(root / "in" / f"push{seed}.parquet", 25.0, seed=seed) for seed in range(3)
    ]
    summary = run_sweep(plan(find_inputs(tables), SPECS, closed_loop=False), root / "out")
    return summary, write_sweep_report(summary, SPECS, root / "sweep.html")


@pytest.fixture(scope="module")
def loaded(swept: tuple[SweepSummary, Path]) -> Iterator[LoadedPage]:
    with open_page(swept[1]) as page:
        yield page


def test_the_summary_is_the_median_of_the_subjects_values(
    swept: tuple[SweepSummary, Path],
) -> None:
    summary, _ = swept
    by_subject, by_run = summary.by_subject, summary.by_run
    assert set(by_subject["subject"]) == {f"push{seed}.parquet" for seed in range(3)}
    medians = by_subject.groupby(["run", "group"], sort=False)[list(STUDY_METRICS)].median()
    expected = by_run.set_index(["run", "group"])[list(STUDY_METRICS)]
    pd.testing.assert_frame_equal(medians.loc[expected.index], expected)
    events = by_subject.groupby(["run", "group"], sort=False)["events"].sum()
    assert (events.loc[expected.index].to_numpy() == by_run["events"].to_numpy()).all()


def test_quartiles_are_numpy_s_over_the_subjects_with_a_value() -> None:
    frame = pd.DataFrame(
        {"run": ["a"] * 5 + ["b"] * 3, "peak_force": [1.0, 4.0, np.nan, 2.0, 9.0, 3.0, 3.0, 5.0]}
    )
    found = quartiles(frame, "peak_force")
    for run, rows in frame.groupby("run"):
        values = rows["peak_force"].to_numpy()
        assert found.loc[run].tolist() == list(np.nanpercentile(values, [25, 75]))


def spec_names(specs: list[ControllerSpec]) -> list[str]:
    return [spec.name for spec in specs]


def test_one_numeric_setting_is_the_x_axis_and_a_run_without_it_a_level() -> None:
    where = layout(SPECS)
    assert where.x == "a1"
    assert [where.xs[name] for name in spec_names(SPECS)] == [5.0, 10.0, 20.0, None]
    assert [where.lines[name] for name in spec_names(SPECS)] == ["adaptive"] * 3 + ["fixed"]


def test_values_spanning_a_decade_or_more_are_on_a_log_axis() -> None:
    assert not layout(SPECS).log_x  # 5 to 20
    assert layout(parse_specs(["adaptive"], sweeps=["adaptive.a1=2,5,10,20"])).log_x
    assert not layout(parse_specs(["adaptive"], sweeps=["adaptive.a1=0,5,10,20"])).log_x


def summary_of(specs: list[ControllerSpec]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A by_run and by_subject of the Cartesian group, three subjects, drawn at random."""
    rng = np.random.default_rng(1)
    runs, subjects = [], []
    for spec in specs:
        values = rng.uniform(0.5, 2.0, size=(3, len(STUDY_METRICS)))
        subjects += [
            {"run": spec.name, "group": "cartesian", "subject": f"S{i}", "events": 2}
            | dict(zip(STUDY_METRICS, row, strict=True))
            for i, row in enumerate(values)
        ]
        counts = {"subjects": 3, "events": 6, "judged": 6, "over": 1}
        medians = dict(zip(STUDY_METRICS, np.median(values, axis=0), strict=True))
        runs.append({"run": spec.name, "group": "cartesian"} | counts | medians)
    return with_over(pd.DataFrame(runs)), pd.DataFrame(subjects)


@pytest.mark.parametrize(
    ("values", "ticks"),
    [("2,5,10,20", "2,5,10,20"), ("5,10,20", ""), ("1:100:50", "1,2,5,10,20,50,100")],
)
def test_the_x_ticks_are_plain_numbers(values: str, ticks: str) -> None:
    specs = parse_specs(["adaptive"], sweeps=[f"adaptive.a1={values}"])
    where = layout(specs)
    with mpl.rc_context(RC):
        figure = draw("cartesian", *summary_of(specs), where)
        figure.canvas.draw()
    shown = [a for a in figure.axes if a.get_visible()]
    assert len(shown) == len(STUDY_METRICS) + 1  # and the share over a limit
    for axes in shown:
        labels = [t.get_text() for t in axes.get_xticklabels() if t.get_text()]
        assert labels and not any("$" in label for label in labels)
        if where.log_x:
            assert labels == ticks.split(",")


@pytest.mark.parametrize("count", [3, 21])
def test_runs_side_by_side_are_named_under_the_axis_up_to_twenty(count: int) -> None:
    specs = parse_specs([f"a{i}=adaptive" for i in range(count)])
    where = layout(specs)
    with mpl.rc_context(RC):
        figure = draw("cartesian", *summary_of(specs), where)
        figure.canvas.draw()
    axes = figure.axes[0]
    labels = [t.get_text() for t in axes.get_xticklabels() if t.get_text()]
    if count <= 20:
        assert labels == [spec.name for spec in specs] and axes.get_xlabel() == ""
    else:
        assert axes.get_xlabel() == "run, in the table's order"


def test_of_two_swept_settings_the_one_with_more_values_is_the_x_axis() -> None:
    specs = parse_specs(["adaptive"], sweeps=["adaptive.a1=5,10,20", "adaptive.a2=1,2"])
    where = layout(specs)
    assert where.x == "a1"
    lines = {where.lines[name] for name in spec_names(specs)}
    assert lines == {"adaptive a2=1", "adaptive a2=2"}


def test_without_a_numeric_setting_that_varies_the_runs_stand_side_by_side() -> None:
    for specs in (
        parse_specs(["adaptive", "fixed"]),
        parse_specs(["adaptive"], sweeps=["adaptive.integrator=euler,zoh"]),
    ):
        where = layout(specs)
        assert where.x is None
        assert where.lines == {name: name for name in spec_names(specs)}


# --- in the browser ---------------------------------------------------------------------------


def test_the_page_has_one_figure_and_one_table_per_group(
    loaded: LoadedPage, swept: tuple[SweepSummary, Path]
) -> None:
    summary, _ = swept
    page = loaded.page
    assert page.title() == f"Sweep report: {summary.root.name}"
    groups = list(dict.fromkeys(summary.by_run["group"]))
    assert page.locator("section[id^=group-]").count() == len(groups) == 2
    for figure in page.locator("svg.figure").all():
        box = figure.bounding_box()
        assert box is not None and box["width"] > 400 and box["height"] > 200
    assert page.locator("table.runs tbody tr").count() == len(SPECS)


def test_each_table_shows_the_summary_s_values(
    loaded: LoadedPage, swept: tuple[SweepSummary, Path]
) -> None:
    summary, _ = swept
    for group, rows in summary.by_run.groupby("group"):
        table = loaded.page.locator(f"#group-{group} table.summary-table tbody tr")
        assert table.count() == len(rows)
        for i, row in enumerate(rows.itertuples(index=False)):
            cells = table.nth(i).locator("th, td").all_inner_texts()
            assert cells[:4] == [row.run, str(row.subjects), str(row.events), str(row.judged)]
            assert cells[5] == number(abs(row.peak_force))


def test_nothing_is_requested_and_nothing_is_logged(loaded: LoadedPage) -> None:
    assert loaded.requests == [loaded.url]
    assert loaded.errors == [] and [m for m in loaded.console if m[0] == "error"] == []


# --- refusals and the command line ------------------------------------------------------------


def test_a_report_path_is_checked_before_any_work(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=r"^--report .*r\.txt: a report is an \.html file$"):
        check_report(tmp_path / "r.txt")
    (tmp_path / "r.html").write_text("kept")
    with pytest.raises(OutputError, match=r"r\.html: already exists; pass --overwrite-report"):
        check_report(tmp_path / "r.html")
    done = hilrig(
        "sweep",
        str(tmp_path / "none.parquet"),
        *SWEEP,
        "-o",
        str(tmp_path / "out"),
        "--report",
        str(tmp_path / "r.html"),
    )
    assert done.returncode != 0
    assert done.stderr.strip().endswith("already exists; pass --overwrite-report to replace it")
    assert (tmp_path / "r.html").read_text() == "kept" and not (tmp_path / "out").exists()


def test_hilrig_sweep_writes_its_report_and_replaces_it_only_when_told(tmp_path: Path) -> None:
    force_table(tmp_path / "push.parquet", 25.0)
    report = tmp_path / "sweep.html"
    args = ["sweep", str(tmp_path / "push.parquet"), *SWEEP, "-o", str(tmp_path / "out")]
    done = hilrig(*args, "--report", str(report), columns=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == f"wrote {report}"
    first = report.read_text()
    assert first.count('<svg class="figure"') == 2
    again = hilrig(*args, "--report", str(report), "--overwrite-report", columns=300)
    assert again.returncode == 0, again.stderr
    assert "0 run" in again.stdout and report.read_text().count('<svg class="figure"') == 2
