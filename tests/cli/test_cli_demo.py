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


def test_demo_writes_the_paper_tables_sessions_comparisons_and_views(tmp_path: Path) -> None:
    for _ in range(2):  # a second demo replaces the first's outputs
        result = subprocess.run(
            [str(HILRIG), "demo", "--out", str(tmp_path)],
            capture_output=True,
            text=True,
            timeout=1200,  # a loaded machine compiling every kernel afresh is slow
        )
        assert result.returncode == 0, result.stderr
    assert result.stdout.count("comparison (change vs fixed)") == 2
    assert "end effector: max offset in mm" in result.stdout
    assert (tmp_path / "paper" / "paper-table.md").exists()
    for scenario, axes in (("paper-end-effector", (0, 1, 2)), ("paper-body", (3, 4))):
        path = tmp_path / f"{scenario}.mcap"
        assert f"recorded {path}" in result.stdout
        assert inspect(path).complete
        state = load(path, topics=["/controller/state"])["/controller/state"]
        peaks = np.array([np.abs(state[f"offset_{i}"]).max() for i in range(9)])
        assert (peaks[list(axes)] > 0.005).all()  # the collided axes yielded
        others = [i for i in range(9) if i not in axes]
        assert (peaks[others] < 0.001).all()  # the others held their task
        replayed = pd.read_parquet(tmp_path / f"{scenario}-replay.parquet")
        assert list(replayed["run"].unique()) == ["adaptive", "variable-stiffness", "fixed"]
        view = Rrd(tmp_path / f"{scenario}.rrd")
        runs = ("recorded", "adaptive", "variable-stiffness", "fixed")
        assert {f"/series/offset/x/{r}" for r in runs} <= view.entities()
        assert f"view: rerun {tmp_path / scenario}.rrd" in result.stdout
