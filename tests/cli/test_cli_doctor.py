"""``hilrig doctor``: the settings and the floor as a reader and a script see them, a bad option
as one line, real-time scheduling refused for real (no CAP_SYS_NICE), and a running session
waited for."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from hilrig.machine import read_settings
from hilrig.rig.machine_lock import WAITING, one_session_at_a_time

HILRIG = Path(sys.executable).with_name("hilrig")
ALLOWED = sorted(os.sched_getaffinity(0))
RUNS_ON = ", ".join(map(str, ALLOWED))
WIDE = {**os.environ, "COLUMNS": "400"}
SETTING_NAMES = [s.name for s in read_settings()]  # the library's (tests/machine checks it)


def doctor(*args: str, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*prefix, str(HILRIG), "doctor", *args],
        capture_output=True,
        text=True,
        timeout=900,  # with the wait for the machine's other sessions (make test beside another)
        env=WIDE,
    )


def complaints(stderr: str) -> list[str]:
    """``stderr``'s lines but for its saying that it waits for a session (``make test`` beside
    another runs sessions)."""
    return [line for line in stderr.splitlines() if line != f"waiting: {WAITING}"]


def test_json_has_every_setting_and_the_floor_counted() -> None:
    result = doctor("--seconds", "0.3", "--json")
    assert (result.returncode, complaints(result.stderr)) == (0, [])
    document: dict[str, Any] = json.loads(result.stdout)
    assert [s["name"] for s in document["settings"]] == SETTING_NAMES
    assert {s["verdict"] for s in document["settings"]} <= {"ok", "warn", "note"}
    floor = document["floor"]
    assert (floor["seconds"], floor["cpu"]) == (0.3, None)
    assert [floor[k]["count"] for k in ("wake_ups", "work", "pty")] == [300, 300, 300]
    assert floor["missed_at_least_pct"] == max(
        floor["wake_ups"]["over_a_period_pct"], floor["pty"]["over_a_period_pct"]
    )


def test_a_port_is_checked_after_the_machine() -> None:
    parent, child = os.openpty()
    try:
        port = os.ttyname(child)
        result = doctor("--seconds", "0", "--json", "--port", port)
    finally:
        os.close(parent)
        os.close(child)
    assert (result.returncode, complaints(result.stderr)) == (0, [])
    settings = json.loads(result.stdout)["settings"]
    assert [s["name"] for s in settings] == [
        *SETTING_NAMES,
        "F/T port",
        "F/T port access",
        "F/T port driver",
    ]
    assert settings[-3]["value"] == port


def test_zero_seconds_reads_the_settings_only() -> None:
    result = doctor("--seconds", "0", "--json")
    assert result.returncode == 0
    assert json.loads(result.stdout)["floor"] is None


def test_the_report_names_each_setting_and_the_floor() -> None:
    result = doctor("--seconds", "0.2", "--cpu", str(ALLOWED[0]))
    assert (result.returncode, complaints(result.stderr)) == (0, [])
    lines = result.stdout.splitlines()
    assert lines[0] == "settings"
    shown = [line.split(":")[0].split(maxsplit=1)[1] for line in lines[1:11]]
    assert shown == SETTING_NAMES
    assert all(line.split()[0] in ("ok", "warn", "note") for line in lines[1:11])
    assert lines[11] == "measuring the timing floor: 0.2 s of wake-ups, 0.2 s of the pty"
    assert f"a bare thread's wake-ups on CPU {ALLOWED[0]}" in result.stdout
    assert lines[-1].startswith("the machine alone spoiled ")
    assert lines[-1].endswith(" hilrig's target of 0.01 %")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--seconds", "-1"], "--seconds -1: must be within 0..3600"),
        (["--seconds", "nan"], "--seconds nan: must be within 0..3600"),
        (["--seconds", "1e9"], "--seconds 1e+09: must be within 0..3600"),
        (["--cpu", "-1"], "--cpu -1: must be a CPU's number, 0 or more"),
        (
            ["--cpu", "4096"],
            f"cpu 4096: the loop's thread may not run there (Invalid argument); it may run on "
            f"{RUNS_ON}",
        ),
    ],
)
def test_a_bad_option_is_one_line(args: list[str], message: str) -> None:
    result = doctor(*args)
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == f"error: {message}\n"


@pytest.mark.skipif(
    shutil.which("setpriv") is None or os.geteuid() != 0, reason="needs setpriv and root"
)
def test_without_cap_sys_nice_real_time_is_refused_and_the_floor_still_measured() -> None:
    no_nice = ("setpriv", "--bounding-set=-sys_nice", "--inh-caps=-sys_nice")
    result = doctor("--seconds", "0.2", "--json", prefix=no_nice)
    assert result.returncode == 0, result.stderr
    document = json.loads(result.stdout)
    realtime = document["settings"][1]
    assert (realtime["value"], realtime["verdict"]) == ("refused", "warn")
    assert realtime["note"].endswith(
        "it needs CAP_SYS_NICE (root has it) or an rtprio limit (limits.conf)"
    )
    assert document["floor"]["sched_fifo"] is False
    assert document["floor"]["wake_ups"]["count"] == 200


def test_a_running_session_is_waited_for() -> None:
    release, held = threading.Event(), threading.Event()

    def session() -> None:
        with one_session_at_a_time(threading.Event()):
            held.set()
            release.wait(60)

    holder = threading.Thread(target=session)
    holder.start()
    assert held.wait(60)
    process = subprocess.Popen(
        [str(HILRIG), "doctor", "--seconds", "0.1", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=WIDE,
    )
    try:
        assert process.stderr is not None
        assert process.stderr.readline() == f"waiting: {WAITING}\n"  # nothing measured yet
        release.set()
        out, err = process.communicate(timeout=900)
    finally:
        release.set()
        holder.join()
        if process.poll() is None:
            process.kill()
    assert (process.returncode, err) == (0, "")
    assert json.loads(out)["floor"]["pty"]["count"] == 100
