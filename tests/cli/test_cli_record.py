"""``hilrig record`` as a lab runs it: a subprocess, a config file, stopped by SIGTERM; its live
view options."""

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from hilrig.recording import inspect, load, recover
from hilrig.rig.machine_lock import STOPPED, WAITING, one_session_at_a_time

HILRIG = Path(sys.executable).with_name("hilrig")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def first_line(process: subprocess.Popen[str]) -> str:
    """The first line ``process`` printed on stderr but for its saying that it waits for another
    session on the machine (``make test`` beside another)."""
    assert process.stderr is not None
    line = process.stderr.readline()
    while line.startswith(f"waiting: {WAITING}"):
        line = process.stderr.readline()
    return line


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
    first = first_line(process)  # printed when the loop starts, however long start-up took
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
        timeout=900,  # with the wait for the machine's other sessions (make test beside another)
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


def record(tmp_path: Path, *args: str, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(HILRIG), "record", "--subject", "S003", *args],
        capture_output=True,
        text=True,
        timeout=900,  # with the wait for the machine's other sessions (make test beside another)
        cwd=tmp_path,
        env={**os.environ, **env},
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--duration", "nan"], "duration nan s: must be a finite number of seconds > 0"),
        (["--duration", "inf"], "duration inf s: must be a finite number of seconds > 0"),
        (["--duration", "0"], "duration 0.0 s: must be a finite number of seconds > 0"),
        (["--rate", "0"], "loop rate 0.0 Hz is not within 1..10000 Hz"),
        (["--rate", "nan"], "loop rate nan Hz is not within 1..10000 Hz"),
        (["--cpu", "-1"], "cpu -1: must be a CPU's number, 0 or more"),
        (
            ["--cpu", "4096"],
            f"cpu 4096: the loop's thread may not run there (Invalid argument); it may run on "
            f"{', '.join(str(cpu) for cpu in sorted(os.sched_getaffinity(0)))}",
        ),
        (
            ["--trajectory", "nope"],
            "unknown trajectory 'nope'; known: circle, square, waypoints, hold",
        ),
        (
            ["--config", "waypoint.toml"],
            "waypoint.toml: [trajectory] trajectory option points[0] must be 4 finite numbers, "
            "got [1.0, 'a', 0.0, 0.0]",
        ),
        (
            ["--config", "flat.toml"],
            "flat.toml: trajectory must be a table ([trajectory] with name = ...)",
        ),
        (
            ["--params", "nope"],
            "unknown preset 'nope'; known: adaptive, adaptive-joint, paper-end-effector, "
            "paper-joint",
        ),
        (["--out", "afile/s.mcap"], "afile/s.mcap: afile is not a folder"),
        (["--out", "afile/new/s.mcap"], "afile/new/s.mcap: afile is not a folder"),
        (["--out", "kept.mcap"], "kept.mcap: already exists; refusing to overwrite it"),
        (["--view-save", "kept.rrd"], "kept.rrd: already exists; refusing to overwrite it"),
        (
            ["--scenario", "hand-contact", "--scenario-set", "stiffness_n_m=-1"],
            "scenario hand-contact: stiffness_n_m -1 must be >= 0",
        ),
        (
            ["--scenario-set", "stiffness"],
            "--scenario-set 'stiffness': expected KEY=VALUE, e.g. stiffness_n_m=800",
        ),
        (
            ["--scenario-set", "depth_m=0.01"],
            "scenario paper-end-effector: no setting 'depth_m'; its settings: period_s",
        ),
        (
            ["--config", "soft.toml", "--scenario-set", "depth_m=0.01"],
            "scenario hand-contact: stiffness_n_m 'soft' is not a number",
        ),
        (
            ["--config", "flat-scenario.toml"],
            "flat-scenario.toml: scenario must be a table ([scenario] with name = ...)",
        ),
    ],
)
def test_a_bad_input_is_one_line_before_any_file_is_made(
    tmp_path: Path, args: list[str], message: str
) -> None:
    (tmp_path / "waypoint.toml").write_text(
        '[trajectory]\nname = "waypoints"\npoints = [[1.0, "a", 0.0, 0.0]]\n'
    )
    (tmp_path / "flat.toml").write_text('trajectory = "circle"\n')
    (tmp_path / "soft.toml").write_text(
        '[scenario]\nname = "hand-contact"\nstiffness_n_m = "soft"\n'
    )
    (tmp_path / "flat-scenario.toml").write_text('scenario = "hand-contact"\n')
    (tmp_path / "afile").write_bytes(b"")
    (tmp_path / "kept.mcap").write_bytes(b"a volunteer's session")
    (tmp_path / "kept.rrd").write_bytes(b"a volunteer's live view")
    before = sorted(p.name for p in tmp_path.iterdir())
    out = [] if "--out" in args else ["--out", "new/session.mcap"]
    result = record(tmp_path, *out, *args)
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == f"error: {message}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no file, no folder
    assert (tmp_path / "kept.mcap").read_bytes() == b"a volunteer's session"
    assert (tmp_path / "kept.rrd").read_bytes() == b"a volunteer's live view"


def test_the_live_view_without_a_display_is_refused_at_once(tmp_path: Path) -> None:
    """On a port of its own: a viewer another program runs on Rerun's default port would be
    used, display or not."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    port = ["--view-port", str(free_port())]
    result = subprocess.run(
        [str(HILRIG), "record", "--subject", "S003", "--out", "s.mcap", "--view", *port],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env,
    )
    assert result.returncode == 2
    assert result.stderr == (
        "error: no display for the Rerun viewer (DISPLAY and WAYLAND_DISPLAY are not set): save "
        "to a file or use the web viewer or a viewer's URL\n"
    )
    assert not list(tmp_path.iterdir())


def holder_of(pid: int, path: Path) -> int:
    """The child process of ``pid`` that has ``path`` open (the recorder of that file)."""
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    for child in map(int, children):
        try:
            fds = list(Path(f"/proc/{child}/fd").iterdir())
        except OSError:
            continue
        for fd in fds:
            try:
                if os.readlink(fd) == str(path):
                    return child
            except OSError:
                continue
    raise AssertionError(f"no child of {pid} has {path} open")


def test_a_killed_recorder_ends_the_session_loudly_and_the_file_can_be_recovered(
    tmp_path: Path,
) -> None:
    out = tmp_path / "session.mcap"
    process = subprocess.Popen(
        [str(HILRIG), "record", "--subject", "S004", "--duration", "120", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert "session started at the start pose" in first_line(process)
        os.kill(holder_of(process.pid, out), signal.SIGKILL)
        stdout, stderr = process.communicate(timeout=120)  # far less than the 120 s asked for
    finally:
        process.kill()
    assert process.returncode == 2
    died = "the recorder process died: robot held, session ended"
    assert f"fault: session: {died}" in stderr
    (ended,) = [line for line in stdout.splitlines() if line.startswith("  ended")]
    assert ended.startswith("  ended early: the recorder process died at ")
    assert ended.endswith(" s; the robot was held")
    incomplete = f"recorder of {out}: exited with code -9"
    assert f"  the file is incomplete: {incomplete}" in stdout
    *_, last = stderr.splitlines()
    assert last.startswith(f"error: the recording is incomplete: {incomplete}")
    assert last.endswith(f"; `hilrig recover {out} -o OUT` restores it")
    # killed as the session started (its first line is printed within half a second): it
    # ended within the watchdog's 100 ticks and the kill's own delay, far from the 120 000 asked
    ticks = int(re.search(r"^  (\d+) ticks, ", stdout, re.M).group(1))  # type: ignore[union-attr]
    assert ticks < 10_000
    recover(out, tmp_path / "recovered.mcap")
    # killed as its first tick ran: on a loaded machine no tick may have reached the disk yet
    # (the session's end-to-end test kills it 1 s in and counts what was lost)
    logged = load(tmp_path / "recovered.mcap").get("/diagnostics/loop")
    assert (0 if logged is None else len(logged)) <= ticks


def test_scenario_settings_drive_the_volunteer_and_are_recorded(tmp_path: Path) -> None:
    config = tmp_path / "volunteer.toml"
    config.write_text('[scenario]\nname = "hand-contact"\nstiffness_n_m = 500\nhold_s = 0.5\n')
    result = record(
        tmp_path,
        "--config", str(config),
        "--scenario-set", "stiffness_n_m=800",  # over the file's 500
        "--scenario-set", "direction_in_base=1,0,0",
        "--scenario-set", "start_s=0.2",
        "--duration", "1.5",
        "--out", "s.mcap",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    session = inspect(tmp_path / "s.mcap").session_info()
    assert session is not None and session.scenario == "hand-contact"
    recorded = session.scenario_settings
    assert recorded["stiffness_n_m"] == 800.0 and recorded["hold_s"] == 0.5
    assert recorded["direction_in_base"] == [1.0, 0.0, 0.0]
    assert recorded["depth_m"] == 0.03  # a default, recorded too
    # the hand pushed along +x in the base frame, so the controller saw a force along x
    state = load(tmp_path / "s.mcap", topics=["/controller/state"])["/controller/state"]
    force = state[["force_0", "force_1", "force_2"]].to_numpy()
    peak = np.abs(force).max(axis=0)
    assert peak[0] > 1.0 and peak[0] > 5 * max(peak[1], peak[2])


def test_ctrl_c_while_waiting_for_the_machine_is_an_interrupt_that_records_nothing(
    tmp_path: Path,
) -> None:
    out = tmp_path / "session.mcap"
    command = [str(HILRIG), "record", "--subject", "S004", "--duration", "2", "--out", str(out)]
    # held by this test (after any session of a run beside this one), the record must wait
    with one_session_at_a_time(threading.Event()):
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        assert process.stderr is not None
        assert process.stderr.readline() == f"waiting: {WAITING}\n"
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130
    assert stderr == f"interrupted: {STOPPED}\n"
    assert stdout == ""
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(
    shutil.which("setpriv") is None or os.geteuid() != 0, reason="needs setpriv and root"
)
def test_a_loop_refused_real_time_is_said_before_the_session_which_runs(tmp_path: Path) -> None:
    no_nice = ["setpriv", "--bounding-set=-sys_nice", "--inh-caps=-sys_nice"]
    result = subprocess.run(
        [
            *no_nice,
            str(HILRIG),
            "record",
            "--subject",
            "S003",
            "--duration",
            "1",
            "--out",
            "s.mcap",
        ],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert warnings == [
        "warning: real-time scheduling: refused - the loop runs at normal priority, behind any "
        "busy process: it needs CAP_SYS_NICE (root has it) or an rtprio limit (limits.conf) "
        "(hilrig doctor)"
    ]
    outcome = inspect(tmp_path / "s.mcap").outcome
    assert outcome is not None and outcome.ticks > 0


@pytest.mark.skipif(
    shutil.which("setpriv") is None or os.geteuid() != 0, reason="needs setpriv and root"
)
def test_a_mistake_is_still_the_one_line_when_the_machine_has_warnings(tmp_path: Path) -> None:
    no_nice = ["setpriv", "--bounding-set=-sys_nice", "--inh-caps=-sys_nice"]
    result = subprocess.run(
        [*no_nice, str(HILRIG), "record", "--subject", "Jane Doe", "--out", "s.mcap"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr.startswith("error: subject id 'Jane Doe' is not a pseudonym")
    assert result.stderr.count("\n") == 1
    assert list(tmp_path.iterdir()) == []
