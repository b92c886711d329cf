"""How a ``hilrig record`` session ended, in its summary and its file (``hilrig info``): its
duration reached, or a signal (SIGINT, SIGTERM) that stopped it; and the sessions it refuses
before any work (a duration over 24 h without --long, an output not named .mcap)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hilrig.recording import inspect
from hilrig.rig.machine_lock import WAITING

HILRIG = Path(sys.executable).with_name("hilrig")


def hilrig(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([HILRIG, *map(str, args)], capture_output=True, text=True, timeout=120)


def without_waiting(stderr: str) -> list[str]:
    """``stderr``'s lines but for its saying that it waits for another session."""
    return [line for line in stderr.splitlines() if not line.startswith(f"waiting: {WAITING}")]


def test_a_session_that_ran_its_course_says_its_duration_was_reached(tmp_path: Path) -> None:
    out = tmp_path / "s.mcap"
    done = hilrig("record", "--subject", "S001", "--duration", "2", "--out", out)
    assert done.returncode == 0, done.stderr
    assert "  ended: duration reached (2.0 s)" in done.stdout.splitlines()
    outcome = inspect(out).outcome
    assert outcome is not None and outcome.ended_by == "duration reached"
    info = hilrig("info", "--check", out)
    assert info.returncode == 0
    assert "ended: duration reached" in info.stdout.splitlines()


@pytest.mark.parametrize(
    ("signum", "ended_by"),
    [
        (signal.SIGINT, "interrupted by the operator (SIGINT)"),
        (signal.SIGTERM, "terminated (SIGTERM)"),
    ],
)
def test_a_signal_ends_the_session_with_a_whole_file_that_says_which(
    tmp_path: Path, signum: signal.Signals, ended_by: str
) -> None:
    out = tmp_path / "s.mcap"
    process = subprocess.Popen(
        [HILRIG, "record", "--subject", "S001", "--duration", "60", "--out", out],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stderr is not None
        line = process.stderr.readline()
        while line and "session started" not in line:  # waits for another session first
            line = process.stderr.readline()
        time.sleep(1.0)
        process.send_signal(signum)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 0, stderr  # stopped as asked: not a failure
    assert "error:" not in stderr
    (ended,) = [line for line in stdout.splitlines() if line.startswith("  ended")]
    assert ended.startswith(f"  ended early: {ended_by} at ")
    assert ended.endswith(" s; the robot was held")
    assert 1.0 <= float(ended.split(" at ")[1].split(" s;")[0]) < 60.0
    info = hilrig("info", "--check", out)
    assert info.returncode == 0, info.stderr  # whole: closed cleanly
    assert f"ended early: {ended_by}" in info.stdout.splitlines()


def test_a_duration_over_24_hours_needs_long(tmp_path: Path) -> None:
    out = tmp_path / "s.mcap"
    refused = hilrig("record", "--subject", "S001", "--duration", "1e12", "--out", out)
    assert refused.returncode == 2
    assert without_waiting(refused.stderr) == [
        "error: --duration 1e+12 s is over 24 h (86400 s): give --long too for a session that long"
    ]
    assert list(tmp_path.iterdir()) == []
    # with --long the duration passes: the output's name is what is refused next
    other = tmp_path / "s.txt"
    named = hilrig("record", "--subject", "S001", "--duration", "1e12", "--long", "--out", other)
    assert named.returncode == 2
    assert without_waiting(named.stderr)[0].startswith(f"error: {other}: a recording is an MCAP")


def test_an_output_not_named_mcap_is_refused_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "new" / "x.txt"
    refused = hilrig("record", "--subject", "S001", "--duration", "2", "--out", out)
    assert refused.returncode == 2
    assert without_waiting(refused.stderr) == [
        f"error: {out}: a recording is an MCAP file, its name must end in .mcap (e.g. x.mcap)"
    ]
    assert list(tmp_path.iterdir()) == []
