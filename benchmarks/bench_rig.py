"""The emulated rig in its own process at 1 kHz while this process's drivers use it.

``hilrig rig serve`` runs as a subprocess (as a lab would run it); here the F/T serial driver
and the joint-state client read it and the Modbus writer sends joint targets every 1 ms for
``DURATION_S``. Measured: achieved rates, joint-state receive latency (the emulated controller
stamps frames with the host monotonic clock, shared across processes), Modbus submit-to-ack
latency, and CPU of each process (utime + stime from /proc over the run).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.harness import Result, quantiles_us
from hilrig.drivers.emulated.rig import HOME_Q_RAD
from hilrig.drivers.ft_serial import FtSerial
from hilrig.drivers.joint_targets import JointTargetsWriter, ModbusEndpoint
from hilrig.drivers.robot_state import RobotStateClient

DURATION_S = 10.0
TICK_NS = 1_000_000
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def endpoint(lines: list[str], label: str) -> str:
    return next(line for line in lines if label in line).rsplit(": ", 1)[1].strip()


def run() -> list[Result]:
    port_dir = Path(tempfile.mkdtemp(prefix="hilrig-bench-"))
    hilrig = Path(sys.executable).with_name("hilrig")
    server = subprocess.Popen(
        [str(hilrig), "rig", "serve", "--port-path", str(port_dir / "ft")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        return measure(server)
    finally:
        server.terminate()
        server.wait(timeout=10)


def measure(server: subprocess.Popen[str]) -> list[Result]:
    """Drive the rig served by ``server`` for DURATION_S and return the results."""
    assert server.stdout is not None
    lines = [server.stdout.readline() for _ in range(5)]
    ft_port = endpoint(lines, "F/T sensor")
    state_host, state_port = endpoint(lines, "joint state").rsplit(":", 1)
    modbus_host, modbus_port = endpoint(lines, "Modbus").rsplit(":", 1)
    latencies_ns: list[int] = []
    write_latencies_ns: list[int] = []
    ft_samples = 0
    with (
        FtSerial(ft_port) as sensor,
        RobotStateClient(state_host, int(state_port)) as state,
        JointTargetsWriter(ModbusEndpoint(modbus_host, int(modbus_port))) as writer,
    ):
        time.sleep(0.5)  # settle: connections, first frames
        sensor.drain()
        server_cpu0, own_cpu0 = cpu_s(server.pid), cpu_s(os.getpid())
        frames0, written0, last_seq = state.decoder_stats().frames, writer.stats.written, -1
        start = time.monotonic_ns()
        deadline = start
        q = np.asarray(HOME_Q_RAD)
        while deadline - start < DURATION_S * 1e9:
            deadline += TICK_NS
            time.sleep(max(0, deadline - time.monotonic_ns()) / 1e9)
            received = state.latest()
            if received is not None and received.state.sequence != last_seq:
                last_seq = received.state.sequence
                latencies_ns.append(received.t_ns - received.state.device_t_ns)
            ft_samples += len(sensor.drain())
            written = writer.stats.written
            writer.write(q)
            if written > written0 + len(write_latencies_ns):
                write_latencies_ns.append(writer.stats.last_latency_ns)
        elapsed_s = (time.monotonic_ns() - start) / 1e9
        server_cpu = (cpu_s(server.pid) - server_cpu0) / elapsed_s * 100
        own_cpu = (cpu_s(os.getpid()) - own_cpu0) / elapsed_s * 100
        state_rate = (state.decoder_stats().frames - frames0) / elapsed_s
        write_rate = (writer.stats.written - written0) / elapsed_s
    ft_rate = ft_samples / elapsed_s
    state_q = quantiles_us(latencies_ns)
    write_q = quantiles_us(write_latencies_ns)
    detail = {"duration_s": elapsed_s, "state_latency_us": state_q, "write_latency_us": write_q}
    return [
        Result("rig", "F/T frames received", ft_rate, "Hz", ">= 990", ft_rate >= 990, detail),
        Result(
            "rig",
            "joint-state frames received",
            state_rate,
            "Hz",
            ">= 990",
            state_rate >= 990,
            detail,
        ),
        Result("rig", "joint-state latency p50", state_q["p50"], "us", "", None, detail),
        Result("rig", "joint-state latency p99", state_q["p99"], "us", "", None, detail),
        Result("rig", "Modbus target writes acknowledged", write_rate, "Hz", "", None, detail),
        Result("rig", "Modbus submit-to-ack p50", write_q["p50"], "us", "", None, detail),
        Result("rig", "Modbus submit-to-ack p99", write_q["p99"], "us", "", None, detail),
        Result("rig", "CPU, emulated rig process", server_cpu, "% of a core", "", None, detail),
        Result("rig", "CPU, driver process", own_cpu, "% of a core", "", None, detail),
    ]
