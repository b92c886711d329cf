"""``hilrig replay FILE --rig emulated``: a recorded collision played into a live session."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from hilrig.recording import inspect, load

HILRIG = Path(sys.executable).with_name("hilrig")
EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"


def test_a_recorded_collision_replayed_into_the_emulated_rig(tmp_path: Path) -> None:
    out = tmp_path / "replayed.mcap"
    result = subprocess.run(
        [
            str(HILRIG),
            "replay",
            str(EXAMPLE),
            "--rig",
            "emulated",
            "--start",
            "2.0",
            "--duration",
            "3.0",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=900,  # with the wait for the machine's other sessions (make test beside another)
    )
    assert result.returncode == 0, result.stderr
    assert f"recorded {out}" in result.stdout
    assert inspect(out).complete
    recorded = load(EXAMPLE, topics=["/controller/state"])["/controller/state"]
    replayed = load(out, topics=["/controller/state", "/events"])
    state = replayed["/controller/state"]
    # the replayed push reached the controller and the robot yielded (nobody else touched it)
    assert state["force_1"].max() > 0.8 * recorded["force_1"].max()
    assert np.abs(state["offset_1"]).max() > 0.01
    assert {"playback started", "playback ended"} <= set(replayed["/events"]["detail"])


def test_rig_replay_refuses_offline_options(tmp_path: Path) -> None:
    result = subprocess.run(
        [str(HILRIG), "replay", str(EXAMPLE), "--rig", "emulated", "--controller", "fixed"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "--rig replays into the live loop's controller" in result.stderr
