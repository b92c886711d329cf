"""``hilrig analyze`` end to end: a real recorded session, replay results, and a folder of
sessions written as one partitioned Parquet dataset."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pyarrow.dataset as ds
import pytest
from analysis_helpers import paper_replay_frame, write_replay, write_session
from typer.testing import CliRunner

from hilrig import analysis
from hilrig.analysis import PARTITIONS, AxisGroup, analyze, load_session, read_dataset
from hilrig.cli import app

EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
HILRIG = Path(sys.executable).with_name("hilrig")


def _analyze(*args: str) -> str:
    result = CliRunner().invoke(app, ["analyze", *args], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.output


def test_the_example_recording_holds_one_end_effector_collision() -> None:
    analysis = analyze(load_session(EXAMPLE))
    (event,) = analysis.events  # the joint torques' noise never lasts 20 ms above 0.2 N*m
    assert event.group is AxisGroup.CARTESIAN
    assert 1.9 < event.duration_s < 2.05  # the paper's 2 s profile
    assert 5.0 < event.peak < 8.0  # |f| of eq. 15-17 peaks at 6.5 N; plus sensor noise
    metrics = {m.axis: m for m in analysis.metrics}
    assert list(metrics) == ["x", "y", "z"]
    for m in metrics.values():
        assert 0.005 < m.max_abs_offset < 0.05  # m: centimetres of avoidance
        assert 0.0 < m.time_to_max_offset_s < event.duration_s
        assert m.recovery_time_s is not None and 0.0 < m.recovery_time_s < 2.0
        assert m.peak_commanded_joint_speed_rad_s is not None
        assert 0.0 < m.peak_commanded_joint_speed_rad_s < 3.14  # within the joint limits
    # fy peaks at +3.5 N, fx at -5 N (eq. 15-16); the offsets follow the forces' signs
    assert metrics["y"].max_offset * metrics["y"].peak_force > 0


def test_analyze_prints_the_events_and_writes_the_comparison(tmp_path: Path) -> None:
    out = tmp_path / "example.csv"
    printed = _analyze(str(EXAMPLE), "--out", str(out))
    assert "collision events" in printed and "cartesian" in printed
    assert "max |offset| mm" in printed and "recovery time s" in printed
    table = pd.read_csv(out)
    assert set(table["run"]) == {"adaptive"}
    rows = table[table["metric"] == "max_abs_offset"].set_index("axis")
    assert list(rows.index) == ["x", "y", "z"]
    assert (rows["unit"] == "m").all() and (rows["value"] > 0.005).all()


def test_the_written_path_is_printed_whole_on_one_line(tmp_path: Path) -> None:
    """Piped output is 80 columns wide: a long path is still one line (to copy), and a path
    is never read as markup."""
    out = tmp_path / "a[red]b" / f"{'comparison-of-the-example-' * 4}.csv"
    out.parent.mkdir()
    printed = _analyze(str(EXAMPLE), "--out", str(out))
    assert f"wrote {out}" in printed.splitlines()


def test_a_replay_compares_every_run_against_the_chosen_baseline(tmp_path: Path) -> None:
    replay = write_replay(tmp_path / "paper.parquet", paper_replay_frame(duration_s=8.0))
    out = tmp_path / "comparison.parquet"
    printed = _analyze(str(replay), "--baseline", "variable-stiffness", "--out", str(out))
    assert "change vs variable-stiffness" in printed
    assert "joint3" not in printed  # no torque on joints 3-6: kept in files, not printed
    table = pd.read_parquet(out)
    adaptive = table[(table["run"] == "adaptive") & (table["metric"] == "max_abs_offset")]
    assert (adaptive.set_index("axis").loc[["x", "y", "z", "joint1"], "change_pct"] > 0).all()


def test_a_folder_of_sessions_becomes_a_partitioned_dataset(tmp_path: Path) -> None:
    sessions = tmp_path / "sessions"
    (sessions / "S001").mkdir(parents=True)
    (sessions / "S002").mkdir()
    write_session(sessions / "S001" / "run.mcap", subject_id="S001", session_id="a", law="fixed")
    # written in three files of 3 s: read as one session
    write_session(sessions / "S002" / "run.mcap", subject_id="S002", session_id="b", split_s=3.0)
    out = tmp_path / "dataset"
    printed = _analyze(str(sessions), "--out", str(out))
    assert "2 sessions: mean over events (change vs fixed)" in printed

    dataset = ds.dataset(out, format="parquet", partitioning="hive")
    frame = dataset.to_table().to_pandas()
    assert set(PARTITIONS) <= set(frame.columns)
    keys = frame[list(PARTITIONS)].drop_duplicates().astype(str).values.tolist()
    assert sorted(keys) == [["S001", "fixed", "a"], ["S002", "adaptive", "b"]]
    assert (out / "subject_id=S002" / "controller=adaptive" / "session_id=b").is_dir()
    # per event and axis: both groups' collisions, every axis of each group
    per_session = frame.groupby("session_id")[["event", "axis"]].value_counts()
    assert per_session.groupby(level=0).size().tolist() == [9, 9]
    assert frame["max_abs_offset"].notna().all()
    assert set(frame["rig"]) == {"emulated"}

    refused = CliRunner().invoke(app, ["analyze", str(sessions / "S001"), "--out", str(out)])
    part = out / "subject_id=S001" / "controller=fixed" / "session_id=a" / "part-0.parquet"
    assert str(refused.exception) == (
        f"{part}: already exists (this session's partition of the dataset); pass --overwrite "
        "to replace it"
    )
    again = _analyze(str(sessions / "S001"), "--out", str(out), "--overwrite")  # that one only
    assert "wrote" in again
    assert len(read_dataset(out)) == len(frame)


def test_a_dataset_of_sessions_without_events_says_nothing_was_written(tmp_path: Path) -> None:
    quiet = write_session(tmp_path / "quiet.mcap", subject_id="S001", session_id="q", duration_s=1)
    assert analyze(load_session(quiet)).events == ()  # the paper's push starts later
    out = tmp_path / "dataset"
    printed = _analyze(str(quiet), "--out", str(out))
    assert printed.splitlines()[-1] == f"no collision events in {quiet}: nothing written to {out}"
    assert "wrote" not in printed
    assert not out.exists()


def test_expected_failures_are_one_line(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("no")
    result = subprocess.run(
        [str(HILRIG), "analyze", str(tmp_path / "notes.txt")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert "not an .mcap session, a .parquet replay or a folder" in result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--baseline", "stiff"], "baseline 'stiff' is not a run here; runs: adaptive"),
        (["--debounce-s", "-1"], "event debounce_s must be finite and >= 0"),
        (["--out", "x.json"], "write a .csv or a .parquet file"),
    ],
)
def test_bad_options_name_the_problem(args: list[str], message: str, tmp_path: Path) -> None:
    if "--out" in args:
        args = ["--out", str(tmp_path / "x.json")]
    result = CliRunner().invoke(app, ["analyze", str(EXAMPLE), *args])
    assert result.exit_code != 0
    assert message in str(result.exception)


def test_sessions_and_replays_together_each_use_a_baseline_they_have(tmp_path: Path) -> None:
    replay = write_replay(tmp_path / "replay.parquet", paper_replay_frame(duration_s=7.0))
    for subject in ("S001", "S002"):
        write_session(tmp_path / f"{subject}.mcap", subject_id=subject, session_id=subject)
    out = tmp_path / "all.csv"
    printed = _analyze(str(tmp_path), "--out", str(out))
    assert "comparison (change vs fixed)" in printed  # the replay has a fixed run
    assert "2 sessions: mean over events (change vs adaptive)" in printed  # they do not
    table = pd.read_csv(out)
    assert set(table["source"].dropna()) == {
        str(replay),
        *(str(p) for p in tmp_path.glob("*.mcap")),
    }
    across = table[table["source"].isna()]
    assert set(across["run"]) == {"adaptive"} and (across["n"] == 2).any()


def test_an_empty_folder_has_nothing_to_analyse(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["analyze", str(tmp_path)])
    assert "no .mcap sessions or .parquet replay results to analyse" in str(result.exception)


def _refused(*args: str) -> str:
    result = CliRunner().invoke(app, ["analyze", *args])
    assert result.exit_code != 0 and result.exception is not None
    return str(result.exception)


def test_an_existing_output_is_refused_unless_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "comparison.csv"
    out.write_text("keep me\n")
    assert _refused(str(EXAMPLE), "--out", str(out)) == (
        f"{out}: already exists; pass --overwrite to replace it"
    )
    assert out.read_text() == "keep me\n"
    _analyze(str(EXAMPLE), "--out", str(out), "--overwrite")
    assert set(pd.read_csv(out)["run"]) == {"adaptive"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["comparison.csv"]  # no temporaries


def test_a_replay_result_or_an_input_is_never_replaced(tmp_path: Path) -> None:
    replay = write_replay(tmp_path / "paper.parquet", paper_replay_frame(duration_s=7.0))
    before = replay.read_bytes()
    assert _refused(str(EXAMPLE), "--out", str(replay), "--overwrite") == (
        f"{replay}: is a replay result; refusing to replace it, even with --overwrite"
    )
    assert _refused(str(replay), "--out", str(replay), "--overwrite") == (
        f"--out {replay}: is also an input; write the results elsewhere"
    )
    assert replay.read_bytes() == before


def test_outputs_are_checked_before_any_input_is_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def unread(*args: object, **kwargs: object) -> None:
        raise AssertionError("an input was read before the output was checked")

    monkeypatch.setattr(analysis, "load_sources", unread)
    (tmp_path / "file").write_text("")
    cases = [
        (["--out", str(tmp_path / "x.json")], "write a .csv or a .parquet file"),
        (["--out", str(tmp_path / "no" / "x.csv")], f"folder {tmp_path / 'no'} does not exist"),
        (["--out", str(tmp_path / "file")], "the dataset goes in a folder, and this is a file"),
    ]
    for args, message in cases:
        assert message in _refused(str(EXAMPLE), *args)


def test_the_baseline_is_checked_before_the_analysis(monkeypatch: pytest.MonkeyPatch) -> None:
    def unanalysed(*args: object, **kwargs: object) -> None:
        raise AssertionError("analysed before the baseline was checked")

    monkeypatch.setattr(analysis, "analyze", unanalysed)
    assert _refused(str(EXAMPLE), "--baseline", "stiff") == (
        "baseline 'stiff' is not a run here; runs: adaptive"
    )


def test_a_comparison_that_fails_to_write_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def failing(self: pd.DataFrame, where: Path, **kwargs: object) -> None:
        Path(where).write_text("half")
        raise OSError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_csv", failing)
    out = tmp_path / "comparison.csv"
    assert _refused(str(EXAMPLE), "--out", str(out)) == f"{out}: cannot write (disk full)"
    assert list(tmp_path.iterdir()) == []


def test_files_claiming_one_id_are_sessions_of_their_own(tmp_path: Path) -> None:
    old_id = "20261207-165147"  # an id of a second's resolution, as two sessions once shared
    for subject in ("S001", "S002"):
        (tmp_path / subject).mkdir()
        write_session(tmp_path / subject / "run.mcap", subject_id=subject, session_id=old_id)
    (tmp_path / "S003").mkdir()
    write_session(tmp_path / "S003" / "run.mcap", subject_id="S003", session_id="c", split_s=3.0)
    sources = analysis.load_sources([tmp_path])
    assert [(s.subject_id, s.session_id) for s in sources] == [
        ("S001", old_id),
        ("S002", old_id),
        ("S003", "c"),  # its three parts, one session
    ]
    whole = load_session([tmp_path / "S001" / "run.mcap"])
    for source in sources:
        assert [len(r.t_s) for r in source.runs] == [len(r.t_s) for r in whole.runs]
