"""``hilrig rig serve`` as its own process: endpoints on stdout at once, clean stop on SIGINT."""

import signal
import socket
import subprocess
import sys
from pathlib import Path

from hilrig.drivers.robot_state.wire import RobotStateDecoder


def test_rig_serve_prints_endpoints_that_work_and_stops_cleanly(tmp_path: Path) -> None:
    hilrig = Path(sys.executable).with_name("hilrig")
    server = subprocess.Popen(
        [
            str(hilrig),
            "rig",
            "serve",
            "--scenario",
            "paper-body",
            "--port-path",
            str(tmp_path / "ft"),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stdout is not None
        lines = [server.stdout.readline() for _ in range(7)]
        assert lines[0].startswith("emulated rig running, scenario paper-body, 1000 Hz")
        assert lines[1].strip() == f"wrist F/T sensor (Kunwei, 460800 8N1): {tmp_path / 'ft'}"
        labels = [line.strip().rsplit(": ", 1)[0] for line in lines[2:6]]
        assert labels == [
            "AUBO ARCS JSON-RPC (TCP)",
            "AUBO ARCS RTDE (TCP)",
            "robot joint state (TCP)",
            "joint targets (Modbus RTU over TCP)",
        ]
        assert lines[6].strip() == "Ctrl-C to stop"
        host, port = lines[4].rsplit(": ", 1)[1].strip().rsplit(":", 1)
        assert host == "127.0.0.1"
        decoder = RobotStateDecoder()
        with socket.create_connection((host, int(port)), timeout=10) as stream:
            while not decoder.feed(stream.recv(4096)):
                pass
        server.send_signal(signal.SIGINT)
        out, _ = server.communicate(timeout=20)
    finally:
        server.kill()
    assert server.returncode == 0
    assert out.startswith("stopped: ") and " F/T frames, " in out


def test_rig_serve_refuses_a_port_path_that_exists_and_leaves_it_alone(tmp_path: Path) -> None:
    existing = tmp_path / "copy-of-a-recording.mcap"
    existing.write_bytes(b"\x89MCAP0\r\n volunteer data")
    hilrig = Path(sys.executable).with_name("hilrig")
    done = subprocess.run(
        [str(hilrig), "rig", "serve", "--port-path", str(existing)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        f"error: {existing}: already exists; the emulated sensor's port is created only where "
        "nothing is"
    ]
    assert existing.read_bytes() == b"\x89MCAP0\r\n volunteer data"
