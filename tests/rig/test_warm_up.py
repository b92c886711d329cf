"""A session's warm-up leaves no compiled code to load once its devices talk: counted in a
fresh process, the compiled signatures (numba overloads) of hilrig's kernels that appear after
the emulated rig is up (its devices connect next) until the session's end must be none."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = """
import json, sys, threading
from pathlib import Path
from numba.core.registry import CPUDispatcher
from hilrig.rig import SessionConfig, record_session

def loaded():
    found = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("hilrig"):
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher) and value.overloads:
                    found[f"{value.__module__}.{value.__name__}"] = len(value.overloads)
    return found

def main():
    up = {}
    config = SessionConfig(
        out=Path(sys.argv[1]), subject_id="W001", scenario="hand-contact", duration_s=0.3
    )
    record_session(config, stop=threading.Event(), rig_ready=lambda rig: up.update(loaded()))
    after = loaded()
    print(json.dumps({
        "before": sorted(up),
        "after": sorted(k for k in after if after[k] != up.get(k)),
    }))

if __name__ == "__main__":
    main()
"""


def test_no_kernel_is_loaded_once_the_devices_talk(tmp_path: Path) -> None:
    script = tmp_path / "session.py"  # a file: the rig's process is spawned from it
    script.write_text(SCRIPT)
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "s.mcap")],
        capture_output=True,
        text=True,
        timeout=900,  # a session may wait for the machine's other one
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    loaded = json.loads(done.stdout.splitlines()[-1])
    kernels = {  # the tick's, the trajectory's, the drivers', the rings', the histograms'
        "hilrig.tick.step_kernel.tick_entry",  # the tick's and its row's, by address
        "hilrig.tick.row.put_tick_row",
        "hilrig.tick.loop_step.loop_entry",
        "hilrig.ring_kernels.put_rows",
        "hilrig.rig.rings.put_first_rows",
        "hilrig.drivers.ft.frames.receive",
        "hilrig.drivers.robot_state.frames.receive",
        "hilrig.tick.trajectory_kernel.circle_into",
        "hilrig.tick.trajectory_kernel.waypoints_into",
        "hilrig.drivers.ft.frames.frame",
        "hilrig.drivers.robot_state.frames.decode",
        "hilrig.drivers.joint_targets.frame.fill_request",
        "hilrig.timing.add_duration",
        "hilrig.rig.loop_figures.add_period",
    }
    assert kernels <= set(loaded["before"])
    assert loaded["after"] == []
