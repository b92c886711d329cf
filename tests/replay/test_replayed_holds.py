"""A session whose emulated rig stopped at its collision's peak (as a loaded host stops it):
closed-loop replay holds on the ticks the live loop held, and still reproduces the force."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

from replay_helpers import HAND, HAND_SECONDS
from typer.testing import CliRunner

from hilrig.cli import app
from hilrig.replay.job import closed_replay_file
from hilrig.replay.results import INPUT_KEY
from hilrig.replay.specs import parse_specs
from hilrig.rig import ControlLoop, LoopConfig, RigProcess, SessionConfig, record_session

STOP_AT_TICK = 2600  # the hand reaches the tool at about 2.5 s and pushes 0.2 s more
STOPPED_S = 0.03  # six times the loop's 5 ms staleness limit


def test_the_recorded_holds_are_replayed_and_the_force_reproduced(tmp_path: Path) -> None:
    rigs: list[RigProcess] = []

    def stop_the_rig(loop: ControlLoop) -> None:
        while loop.summary.ticks < STOP_AT_TICK:  # session time, however long warm-up took
            time.sleep(0.001)
        pid = rigs[0].pid
        assert pid is not None
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(STOPPED_S)
        finally:
            os.kill(pid, signal.SIGCONT)

    def on_start(loop: ControlLoop) -> None:
        threading.Thread(target=stop_the_rig, args=(loop,), daemon=True).start()

    path = tmp_path / "stopped.mcap"
    config = SessionConfig(
        out=path,
        subject_id="V001",
        scenario="hand-contact",
        scenario_settings=dict(HAND),
        duration_s=HAND_SECONDS,
        trajectory="hold",
        loop=LoopConfig(law="adaptive"),
    )
    result = record_session(
        config, stop=threading.Event(), on_start=on_start, rig_ready=rigs.append
    )
    held = result.summary.hold_ticks
    assert held >= 10  # the rig's 30 ms stop held the loop (its own stalls may add more)
    assert result.drops == 0
    record = closed_replay_file(path, parse_specs(["fixed"])).table.attrs[INPUT_KEY]["closed_loop"]
    assert record["recorded_link_holds"] == held
    # both laws, the recorded one re-simulated and the other, hold on the recorded ticks (and
    # only there: neither stopped)
    assert record["stopped"] == [False, False]
    assert record["hold_ticks"] == [held, held]
    (collision,) = record["collisions"]
    assert collision["reproduction_peak_error_pct"] <= 5.0
    assert collision["reproduction_impulse_error_pct"] <= 5.0
    output = CliRunner().invoke(app, ["replay", str(path), "--closed-loop", "-c", "fixed"])
    assert output.exit_code == 0, output.output
    line = f"the live loop held {held} ticks for a stale link or a failed command: every run holds"
    assert f"\n{line} on them too\n" in output.stdout
    assert output.stdout.count(f"; {held} hold ticks") == 1  # the fixed law's prediction
