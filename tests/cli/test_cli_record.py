"""``hilrig record`` as a lab runs it: a subprocess, a config file, stopped by SIGTERM; its live
view options."""

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

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


def test_view_save_writes_the_live_view_beside_a_complete_recording(tmp_path: Path) -> None:
    out, live = tmp_path / "session.mcap", tmp_path / "live.rrd"
    command = ["record", "--subject", "S003", "--duration", "2", "--out", str(out)]
    result = subprocess.run(
        [str(HILRIG), *command, "--view-save", str(live)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert re.search(r"live view: (\d+) batches shown, \1 sent, 0 dropped$", result.stdout, re.M)
    assert inspect(out).complete
    entities = {c.entity_path for c in RrdReader(live).stream().to_chunks() if not c.is_static}
    assert {"/series/input/x", "/world/robot/links", "/events"} <= entities


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (
            ["--view-url", "http://127.0.0.1:9876"],
            "live view URL 'http://127.0.0.1:9876': expected",
        ),
        (["--view-save", "/no/such/dir/live.rrd"], "directory /no/such/dir does not exist"),
        (["--view", "--view-save", "live.rrd"], "--view and --view-save: choose one"),
    ],
)
def test_a_bad_live_view_option_is_one_line_before_anything_starts(
    tmp_path: Path, option: list[str], message: str
) -> None:
    out = tmp_path / "session.mcap"
    result = subprocess.run(
        [str(HILRIG), "record", "--subject", "S003", "--out", str(out), *option],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and message in result.stderr
    assert not out.exists()
