"""``hilrig record`` as a lab runs it: a subprocess, a config file, stopped by SIGTERM."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hilrig.recording import inspect, load

HILRIG = Path(sys.executable).with_name("hilrig")


def test_sigterm_finishes_the_file_and_waypoints_come_from_the_config(tmp_path: Path) -> None:
    config = tmp_path / "session.toml"
    config.write_text(
        '[trajectory]\nname = "waypoints"\n'
        "points = [[1.0, 0.0, 0.02, 0.0], [2.0, 0.02, 0.02, 0.0]]\n"
    )
    out = tmp_path / "session.mcap"
    process = subprocess.Popen(
        [
            str(HILRIG),
            "record",
            "--subject",
            "S002",
            "--config",
            str(config),
            "--scenario",
            "paper-body",
            "--duration",
            "60",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stderr is not None
    first = process.stderr.readline()  # printed when the loop starts, however long start-up took
    assert "session started at the start pose" in first
    time.sleep(2.5)  # the path reaches its last waypoint 2 s after the loop starts
    process.send_signal(signal.SIGTERM)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 0, stderr
    assert stdout.startswith(f"recorded {out}")
    info = inspect(out)
    assert info.complete  # closed cleanly: summary written, nothing to recover
    desired = load(out, topics=["/trajectory/desired"])["/trajectory/desired"]
    position = desired[["pose.position.x", "pose.position.y"]].to_numpy()
    moved = position[-1] - position[0]
    np.testing.assert_allclose(moved, [0.02, 0.02], atol=1e-3)  # reached the second waypoint
