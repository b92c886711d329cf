"""A session against a rig served alone, as against a real arm: ``hilrig rig serve --json``
prints its endpoints, ``hilrig record --rig aubo`` drives its ARCS controller through AUBO's
client with them, and the session meets the same collision and gets the same safety verdict as
the emulated default's. ``hilrig doctor --robot`` checks that controller first."""

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hilrig.analysis import analyze, load_session
from hilrig.emulator.arcs import ArcsConfig
from hilrig.emulator.rig import RigConfig
from hilrig.rig import RigProcess
from hilrig.rig.machine_lock import WAITING

HILRIG = Path(sys.executable).with_name("hilrig")
SERVO, STATE = "/robot/servo", "/controller/state"
SESSION_S = "7"  # the paper's end-effector collision comes 4 s to 6 s into a session


@pytest.fixture(scope="module")
def served() -> Iterator[dict[str, str]]:
    server = subprocess.Popen(
        [str(HILRIG), "rig", "serve", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stdout is not None
        yield json.loads(server.stdout.readline())
        server.send_signal(signal.SIGINT)
        server.communicate(timeout=60)
    finally:
        server.kill()


def _config(tmp: Path, endpoints: dict[str, str]) -> Path:
    host, rpc_port = endpoints["aubo_rpc"].rsplit(":", 1)
    rtde_port = endpoints["aubo_rtde"].rsplit(":", 1)[1]
    path = tmp / "rig.toml"
    path.write_text(
        f'[endpoints]\nft_wrist_port = "{endpoints["ft_wrist_port"]}"\n'
        f'[robot]\nhost = "{host}"\nrpc_port = {rpc_port}\nrtde_port = {rtde_port}\n'
    )
    return path


def _hilrig(*args: str, password: str = "123456") -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "HILRIG_AUBO_PASSWORD": password}
    return subprocess.run(
        [str(HILRIG), *args], capture_output=True, text=True, timeout=900, env=env
    )


def test_rig_serve_prints_its_endpoints_as_one_json_object(served: dict[str, str]) -> None:
    assert set(served) == {"ft_wrist_port", "aubo_rpc", "aubo_rtde", "robot_state", "modbus"}
    for name in ("aubo_rpc", "aubo_rtde", "robot_state", "modbus"):
        host, port = served[name].rsplit(":", 1)
        assert host == "127.0.0.1" and int(port) > 0


def test_doctor_checks_the_controller(served: dict[str, str]) -> None:
    host, rpc_port = served["aubo_rpc"].rsplit(":", 1)
    rtde_port = served["aubo_rtde"].rsplit(":", 1)[1]
    args = ("doctor", "--seconds", "0", "--json", "--robot", host)
    ports = ("--robot-rpc-port", rpc_port, "--robot-rtde-port", rtde_port)
    result = _hilrig(*args, *ports)
    assert result.returncode == 0, result.stderr
    controller = json.loads(result.stdout)["controller"]
    assert controller["problem"] == ""
    assert controller["robot"] == "rob1"
    assert controller["interface_version"] == 24001
    assert (controller["robot_mode"], controller["safety_mode"]) == (8, 1)
    assert controller["rtde_samples"] > 0
    refused = _hilrig(*args, *ports, password="wrong")
    assert refused.returncode == 1
    problem = json.loads(refused.stdout)["controller"]["problem"]
    assert "Login failed: wrong user or password" in problem
    assert "wrong" not in problem.replace("wrong user", "")


def test_a_session_on_the_served_rig_meets_the_default_s_collision(
    served: dict[str, str], tmp_path: Path
) -> None:
    common = ("--subject", "S001", "--duration", SESSION_S)
    aubo = tmp_path / "aubo.mcap"
    result = _hilrig(
        "record",
        "--rig",
        "aubo",
        "--config",
        str(_config(tmp_path, served)),
        "--body-region",
        "hand",
        "--out",
        str(aubo),
        *common,
    )
    assert result.returncode == 0, result.stderr
    default = tmp_path / "default.mcap"
    result = _hilrig("record", "--out", str(default), *common)
    assert result.returncode == 0, result.stderr
    on_aubo, on_default = (analyze(load_session(path)) for path in (aubo, default))
    assert [e.group for e in on_aubo.events] == [e.group for e in on_default.events]
    assert len(on_aubo.events) >= 1
    # the served rig's volunteer clock starts with the first servoJoint, the default's just
    # before the first tick: the time between them is the start-up's, whatever the load
    lead_s = _servo_lead_s(aubo)
    for a, b in zip(on_aubo.events, on_default.events, strict=True):
        assert a.start_s + lead_s == pytest.approx(b.start_s, abs=0.05)
        assert a.peak == pytest.approx(b.peak, rel=0.05)
    assert [v.verdict for v in on_aubo.verdicts] == [v.verdict for v in on_default.verdicts]
    assert on_aubo.verdicts


def _servo_lead_s(path: Path) -> float:
    """How long before a session's first controller state its first servoJoint call was
    recorded (the official MCAP reader)."""
    first: dict[str, int] = {}
    with path.open("rb") as stream:
        reader = make_reader(stream)
        for _, channel, message in reader.iter_messages(topics=[SERVO, STATE]):
            first.setdefault(channel.topic, message.log_time)
    return (first[STATE] - first[SERVO]) / 1e9


def test_a_killed_session_leaves_servo_mode(tmp_path: Path) -> None:
    """SIGKILL of ``hilrig record``: its link's process sees its pipe close and leaves servo
    mode itself (the controller here never ends servo mode on its own)."""
    config = RigConfig(
        scenario_starts_at_open=False,
        scenario_starts_with_servo=True,
        arcs=ArcsConfig(servo_timeout_s=3600.0),
    )
    rig = RigProcess("paper-end-effector", config=config)
    endpoints = rig.start()
    try:
        served = {
            "ft_wrist_port": endpoints.ft_wrist_port,
            "aubo_rpc": ":".join(map(str, endpoints.aubo_rpc)),
            "aubo_rtde": ":".join(map(str, endpoints.aubo_rtde)),
        }
        args = ("record", "--rig", "aubo", "--config", str(_config(tmp_path, served)))
        process = subprocess.Popen(
            [str(HILRIG), *args, "--subject", "S001", "--out", str(tmp_path / "k.mcap")],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "HILRIG_AUBO_PASSWORD": "123456"},
        )
        try:
            assert "session started at the start pose" in first_line(process)
            assert rig.counters().servo_mode is True
        finally:
            process.kill()
        process.wait(timeout=60)
        for _ in range(600):  # the link's process notices the closed pipe within its period
            if not rig.counters().servo_mode:
                break
            time.sleep(0.05)
        assert rig.counters().servo_mode is False
    finally:
        rig.stop()


def first_line(process: subprocess.Popen[str]) -> str:
    """The first line ``process`` printed on stderr but for its waiting for the machine."""
    assert process.stderr is not None
    line = process.stderr.readline()
    while line.startswith(f"waiting: {WAITING}"):
        line = process.stderr.readline()
    return line
