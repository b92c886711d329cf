"""A study assembled from its folder: exclusions leave exactly the study without them, sessions
that cannot be analysed are left out with the reason, the analyses are kept and reused."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
from study_helpers import write_study, write_study_session

from hilrig.errors import StudyError
from hilrig.study import stats
from hilrig.study.assemble import ReportOptions, assemble
from hilrig.study.records import COMPARISON_COLUMNS, STUDY_METRICS
from hilrig.study.study_file import StudyFile, exclude
from hilrig.study.study_file import write_study as write_study_file

SUBJECTS = ("S001", "S002", "S003", "S004")
LAWS = ("adaptive", "fixed")
OPTIONS = ReportOptions(resamples=999)


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("study")
    write_study(root, SUBJECTS, LAWS, duration_s=7.0)
    return root


def _copy(study: Path, to: Path, *, without: tuple[str, ...] = ()) -> Path:
    shutil.copytree(study, to, ignore=shutil.ignore_patterns(".hilrig-study", "study.toml"))
    for name in without:
        (to / name.split("-")[0] / f"{name}.mcap").unlink()
    return to


def _numbers(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.reset_index(drop=True)


def test_the_statistics_are_those_of_its_observations(study: Path) -> None:
    report = assemble(study, OPTIONS, "hilrig report study -o r.html")
    assert report.baseline == "fixed"  # the paper's baseline when it is there
    assert set(report.observations["metric"]) <= set(STUDY_METRICS)
    assert len(report.observations) == len(SUBJECTS) * len(LAWS) * 2 * len(STUDY_METRICS)
    values = stats.subject_values(report.observations)
    pd.testing.assert_frame_equal(report.subject_values, values)
    pd.testing.assert_frame_equal(
        report.comparisons, stats.comparisons(values, "fixed", resamples=999)
    )
    assert list(report.comparisons.columns) == list(COMPARISON_COLUMNS)
    paired = report.comparisons[report.comparisons["metric"] == "max_abs_offset"]
    assert (paired["design"] == "paired").all() and (paired["n_condition"] == 4).all()
    assert report.design_text == (
        "adaptive vs fixed: 4 subjects saw both (paired, within-subject)",
    )
    assert {(c.condition, c.group) for c in report.curves} == {
        (law, group) for law in LAWS for group in ("cartesian", "joint")
    }
    for curve in report.curves:
        assert curve.t_s[0] < 0 < curve.t_s[-1]
        assert curve.force.shape == curve.damping.shape == curve.zeta.shape == curve.t_s.shape


def test_an_excluded_session_gives_the_study_without_it(study: Path, tmp_path: Path) -> None:
    curated = _copy(study, tmp_path / "curated")
    write_study_file(curated, exclude(StudyFile(), "S002-adaptive", "stepped back early"))
    without = _copy(study, tmp_path / "without", without=("S002-adaptive",))
    a = assemble(curated, OPTIONS, "")
    b = assemble(without, OPTIONS, "")
    for name in ("observations", "subject_values", "distributions", "comparisons"):
        pd.testing.assert_frame_equal(_numbers(getattr(a, name)), _numbers(getattr(b, name)))
    row = a.catalogue.set_index("session").loc["S002-adaptive"]
    assert row["excluded"] == "stepped back early"
    assert a.exclusions.to_dict("records") == [
        {
            "target": "S002-adaptive",
            "reason": "stepped back early",
            "removed": "1 session (1 collisions logged)",
        }
    ]
    assert "3 subjects saw both (paired on them); 1 saw only one" in a.design_text[0]


def test_an_excluded_event_leaves_only_that_event_out(study: Path, tmp_path: Path) -> None:
    curated = _copy(study, tmp_path / "curated")
    whole = assemble(curated, OPTIONS, "")
    write_study_file(curated, exclude(StudyFile(), "S003-fixed", "sensor bumped", [1]))
    less = assemble(curated, OPTIONS, "")
    gone = (whole.observations["session"] == "S003-fixed") & (whole.observations["event"] == 1)
    expected = whole.observations[~gone].reset_index(drop=True)
    pd.testing.assert_frame_equal(less.observations, expected)
    assert less.exclusions["removed"].tolist() == ["1 event"]


def test_what_cannot_be_analysed_is_left_out_with_the_reason(study: Path, tmp_path: Path) -> None:
    root = _copy(study, tmp_path / "odd")
    (root / "junk.mcap").write_bytes(b"\x89MCAP0\r\nbut then nothing")
    write_study_session(
        root / "S009" / "S009-fixed.mcap",
        subject="S009",
        law="fixed",
        scale=1.0,
        session_id="S009-fixed",
        duration_s=3.0,
    )  # the collision starts at 4 s: no event at all
    write_study_file(root, exclude(StudyFile(), "S003-adaptive", "r", [7]))
    report = assemble(root, OPTIONS, "")
    excluded = report.catalogue.set_index("session")["excluded"]
    assert excluded["junk.mcap"].startswith("unreadable: ")
    assert excluded["S009-fixed"] == ""  # analysed: no collision in it, nothing to compare
    assert "S009" not in set(report.observations["subject"])
    assert "study.toml excludes event 7 of S003-adaptive, which has no such event" in report.notes


def test_analyses_are_kept_and_reused_until_a_file_changes(study: Path, tmp_path: Path) -> None:
    root = _copy(study, tmp_path / "kept")
    steps: list[tuple[str, int, int]] = []
    assemble(root, OPTIONS, "", step=lambda *s: steps.append(s))
    stored = sorted((root / ".hilrig-study" / "metrics").glob("*.parquet"))
    assert len(stored) == len(SUBJECTS) * len(LAWS)
    assert ("analysing", 8, 8) in steps and ("indexing", 8, 8) in steps
    before = {p: p.stat().st_mtime_ns for p in stored}
    steps.clear()
    assemble(root, OPTIONS, "", step=lambda *s: steps.append(s))
    assert not [s for s in steps if s[0] == "indexing"]
    assert {p: p.stat().st_mtime_ns for p in stored} == before  # read, not written again


def test_a_study_with_nothing_to_compare_is_refused(tmp_path: Path) -> None:
    with pytest.raises(StudyError, match=r"no recordings \(\*\.mcap\) in it or its sub-folders$"):
        assemble(tmp_path, OPTIONS, "")
    write_study_session(
        tmp_path / "a.mcap",
        subject="S001",
        law="fixed",
        scale=1.0,
        session_id="a",
        duration_s=3.0,
    )
    with pytest.raises(StudyError, match="no collision events left to compare"):
        assemble(tmp_path, OPTIONS, "")


def test_an_unknown_baseline_is_refused(study: Path, tmp_path: Path) -> None:
    root = _copy(study, tmp_path / "b")
    with pytest.raises(
        StudyError, match=r"^baseline 'pid' is not a condition; conditions: adaptive, fixed$"
    ):
        assemble(root, ReportOptions(baseline="pid", resamples=999), "")
