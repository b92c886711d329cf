"""Sweeping a study: the events ``study.toml`` excludes are left out of every run's rows, found
by group and time window (a task numbers the events of one file, the study those of a whole
session), and a folder swept with other exclusions is refused."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from sweep_helpers import write_session

from hilrig.replay import parse_specs
from hilrig.study.study_file import StudyFile, exclude, write_study
from hilrig.sweep import SweepError, find_inputs, plan, read_sweep, sweep

SPECS = parse_specs(["adaptive"], sweeps=["adaptive.a1=5,20"])
KEY = ["source", "run", "event", "axis"]


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two 8 s sessions with a joint event (3.52-5.48 s) and a Cartesian one (4.02-5.98 s),
    the second split into 3.25 s parts (its events fall in the second part)."""
    root = tmp_path_factory.mktemp("study")
    (root / "lab").mkdir()
    write_session(root / "lab" / "A.mcap", subject_id="S001", session_id="A")
    write_session(root / "lab" / "B.mcap", subject_id="S002", session_id="B", split_s=3.25)
    return root


def swept(sources: list[Path], out: Path) -> pd.DataFrame:
    inputs = find_inputs(sources)
    sweep(plan(inputs, SPECS, closed_loop=False), out)
    return read_sweep(out).sort_values(KEY, ignore_index=True)


def test_excluded_events_are_left_out_by_group_and_time(study: Path, tmp_path: Path) -> None:
    everything = swept([study / "lab"], tmp_path / "all")  # a folder: nothing excluded
    assert set(everything["source"]) == {"A.mcap", "B_001.mcap"}  # B's other parts: no event
    events = everything.groupby(["source", "group"])["event"].nunique().to_dict()
    assert events == {
        ("A.mcap", "cartesian"): 1,
        ("A.mcap", "joint"): 1,
        ("B_001.mcap", "cartesian"): 1,
        ("B_001.mcap", "joint"): 1,
    }
    # the study numbers A's events 0 (joint) and 1 (Cartesian), and B's the same
    study_file = exclude(StudyFile(), "A", "hand slipped", events=[1])
    study_file = exclude(study_file, "B", "sensor bumped", events=[0])
    write_study(study, exclude(study_file, "B", "sensor bumped", events=[0, 7]))
    inputs = find_inputs([study])
    assert inputs.notes == (
        f"study {study}: 2 sessions (4 files); left out: 0 excluded in study.toml, 0 unreadable; "
        "events excluded in study.toml: 2 left out (by group and time), 1 not in their sessions",
    )
    got = swept([study], tmp_path / "study")
    # Study sources are named from the study folder; A loses its Cartesian event, the part of
    # B holding its joint event loses that one (its Cartesian event overlaps it in time: kept)
    got["source"] = got["source"].str.removeprefix("lab/")
    dropped = ((everything["source"] == "A.mcap") & (everything["group"] == "cartesian")) | (
        (everything["source"] == "B_001.mcap") & (everything["group"] == "joint")
    )
    expected = everything[~dropped].reset_index(drop=True)
    assert 0 < len(expected) < len(everything)
    pd.testing.assert_frame_equal(
        got.drop(columns="input"), expected.drop(columns="input"), check_like=True
    )


def test_a_folder_swept_with_other_exclusions_is_refused(study: Path, tmp_path: Path) -> None:
    write_study(study, exclude(StudyFile(), "A", "hand slipped", events=[1]))
    out = tmp_path / "out"
    swept([study], out)
    write_study(study, StudyFile())  # the exclusion withdrawn
    with pytest.raises(SweepError) as raised:
        swept([study], out)
    assert str(raised.value) == (
        f"--out {out}: source 'lab/A.mcap' was swept there with other excluded events (1, now "
        "0; the study file changed?); choose another folder"
    )
    assert len(swept([study], tmp_path / "fresh")) > len(read_sweep(out))
