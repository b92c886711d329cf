"""``hilrig demo``, the README's main job, end to end."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from hilrig.recording import inspect, load

HILRIG = Path(sys.executable).with_name("hilrig")


def test_demo_writes_the_paper_tables_and_two_complete_sessions(tmp_path: Path) -> None:
    result = subprocess.run(
        [str(HILRIG), "demo", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
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
