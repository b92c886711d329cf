"""``hilrig demo``, the README's main job, end to end."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from hilrig.recording import inspect, load

sys.path.insert(0, str(Path(__file__).parents[1] / "viz"))
from rrd_helpers import Rrd

HILRIG = Path(sys.executable).with_name("hilrig")


def demo(out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(HILRIG), "demo", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=1200,  # a loaded machine compiling every kernel afresh is slow
    )


def test_demo_writes_the_paper_tables_sessions_comparisons_and_views(tmp_path: Path) -> None:
    out = tmp_path / "a[red]b"  # file names are shown as they are, never read as markup
    result = demo(out)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("comparison (change vs fixed)") == 2
    assert "end effector: max offset in mm" in result.stdout
    assert f"paper tables and figures in {out / 'paper'}" in result.stdout
    assert (out / "paper" / "paper-table.md").exists()
    for scenario, axes in (("paper-end-effector", (0, 1, 2)), ("paper-body", (3, 4))):
        path = out / f"{scenario}.mcap"
        assert f"recorded {path}" in result.stdout
        assert inspect(path).complete
        state = load(path, topics=["/controller/state"])["/controller/state"]
        peaks = np.array([np.abs(state[f"offset_{i}"]).max() for i in range(9)])
        assert (peaks[list(axes)] > 0.005).all()  # the collided axes yielded
        others = [i for i in range(9) if i not in axes]
        assert (peaks[others] < 0.001).all()  # the others held their task
        replayed = pd.read_parquet(out / f"{scenario}-replay.parquet")
        assert list(replayed["run"].unique()) == ["adaptive", "variable-stiffness", "fixed"]
        view = Rrd(out / f"{scenario}.rrd")
        runs = ("recorded", "adaptive", "variable-stiffness", "fixed")
        assert {f"/series/offset/x/{r}" for r in runs} <= view.entities()
        assert f"view: rerun {out / scenario}.rrd" in result.stdout
    study = out / "study"
    assert "study (4 volunteers x adaptive, fixed, hand-contact)" in result.stdout
    assert len(list(study.rglob("*.mcap"))) == 8  # 4 volunteers x 2 controllers, once each
    assert (study / "simulation.toml").exists()
    report = out / "study-report.html"
    assert f"wrote {report}: 8 sessions of 4 subjects, 0 excluded" in result.stdout
    assert "adaptive vs fixed: 4 subjects saw both" in report.read_text(encoding="utf-8")
    # no temporary left (the study's catalogue and analyses are kept in .hilrig-study)
    assert [p.relative_to(out) for p in out.rglob(".*")] == [Path("study/.hilrig-study")]
    # a second demo into the same folder overwrites nothing and says so before any work
    files = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    again = demo(out)
    assert (again.returncode, again.stdout) == (2, "")
    assert again.stderr == (
        f"error: {out / 'paper' / 'paper-table.md'}: already exists; refusing to overwrite it; "
        "choose another --out, or move the earlier outputs away\n"
    )
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == files


def test_a_recording_in_the_way_is_refused_before_any_work(tmp_path: Path) -> None:
    kept = tmp_path / "paper-end-effector.mcap"
    kept.write_bytes(b"a volunteer's session")
    result = demo(tmp_path)
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == (
        f"error: {kept}: already exists; refusing to overwrite it; choose another --out, or "
        "move the earlier outputs away\n"
    )
    assert list(tmp_path.iterdir()) == [kept]  # no paper folder, no session
    assert kept.read_bytes() == b"a volunteer's session"


def test_an_output_folder_under_a_file_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "afile").write_bytes(b"")
    result = demo(tmp_path / "afile" / "demo")
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == (
        f"error: {tmp_path / 'afile' / 'demo' / 'paper' / 'paper-table.md'}: "
        f"{tmp_path / 'afile'} is not a folder; choose another --out, or move the earlier "
        "outputs away\n"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]
