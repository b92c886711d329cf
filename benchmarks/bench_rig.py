"""The emulated rig in its own process at 1 kHz while a client reads and writes at 1 kHz.

The rig runs as the sessions run it (:class:`RigProcess`); this process reads the F/T pty and
the joint-state stream and sends one Modbus joint-target write (pymodbus RTU client, answered
before the next) every 1 ms for ``DURATION_S``, through :class:`RigProbe` (plain wire clients,
no hilrig driver). Measured: the rig process's CPU (utime + stime from /proc over wall time;
target <= 25 % of a core), frames received against the rig's own sent counters, joint-state
receive latency (the emulated controller stamps frames with the host monotonic clock) and
Modbus write round trips. ``python -m benchmarks.bench_rig`` prints them.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from benchmarks.harness import Result, quantiles_us
from hilrig.emulator.probe import RigProbe
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.rig.rig_process import RigProcess

DURATION_S = 10.0
TICK_NS = 1_000_000
CPU_TARGET_PERCENT = 25.0
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run() -> list[Result]:
    rig = RigProcess("paper-end-effector")
    endpoints = rig.start()
    try:
        assert rig.pid is not None
        with RigProbe(endpoints) as probe:
            return measure(rig, rig.pid, probe)
    finally:
        rig.stop()


def measure(rig: RigProcess, pid: int, probe: RigProbe) -> list[Result]:
    """Drive the rig for DURATION_S through ``probe`` and return the results."""
    deadline = time.monotonic() + 0.5  # settle: connections, first frames
    while time.monotonic() < deadline:
        probe.read(0.01)
    latencies_ns: list[int] = []
    write_ns: list[int] = []
    ft_received = state_received = 0
    q = np.asarray(HOME_Q_RAD)
    before = rig.counters()
    rig_cpu0, own_cpu0 = cpu_s(pid), cpu_s(os.getpid())
    start = tick = time.monotonic_ns()
    while tick - start < DURATION_S * 1e9:
        tick += TICK_NS
        time.sleep(max(0, tick - time.monotonic_ns()) / 1e9)
        samples, states = probe.read()
        now = time.monotonic_ns()
        ft_received += len(samples)
        state_received += len(states)
        latencies_ns += [now - state.device_t_ns for state in states]
        probe.write(q.tolist(), len(write_ns) + 1)
        write_ns.append(time.monotonic_ns() - now)
    elapsed_s = (time.monotonic_ns() - start) / 1e9
    rig_cpu = (cpu_s(pid) - rig_cpu0) / elapsed_s * 100
    own_cpu = (cpu_s(os.getpid()) - own_cpu0) / elapsed_s * 100
    after = rig.counters()
    ft_sent = after.ft_frames_sent - before.ft_frames_sent
    state_sent = after.joint_frames_sent - before.joint_frames_sent
    state_q, write_q = quantiles_us(latencies_ns), quantiles_us(write_ns)
    detail = {
        "duration_s": elapsed_s,
        "state_latency_us": state_q,
        "write_latency_us": write_q,
        "rig_counters": after.__dict__,
        "ft_frames_sent": ft_sent,
        "joint_frames_sent": state_sent,
    }
    ft_rate, state_rate = ft_received / elapsed_s, state_received / elapsed_s
    writes = after.modbus_writes - before.modbus_writes
    return [
        Result(
            "rig",
            "CPU, emulated rig process",
            rig_cpu,
            "% of a core",
            f"<= {CPU_TARGET_PERCENT:g}",
            rig_cpu <= CPU_TARGET_PERCENT,
            detail,
        ),
        Result("rig", "F/T frames received", ft_rate, "Hz", ">= 990", ft_rate >= 990, detail),
        Result("rig", "joint-state frames received", state_rate, "Hz", ">= 990", None, detail),
        Result("rig", "rig slots late", after.slots_late - before.slots_late, "slots", "", None),
        Result("rig", "joint-state latency p50", state_q["p50"], "us", "", None, detail),
        Result("rig", "joint-state latency p99", state_q["p99"], "us", "", None, detail),
        Result("rig", "Modbus writes applied", writes / elapsed_s, "Hz", "", None, detail),
        Result("rig", "Modbus write round trip p50", write_q["p50"], "us", "", None, detail),
        Result("rig", "Modbus write round trip p99", write_q["p99"], "us", "", None, detail),
        Result("rig", "CPU, client process", own_cpu, "% of a core", "", None, detail),
    ]


if __name__ == "__main__":
    for result in run():
        print(f"{result.name}: {result.value:.1f} {result.unit} {result.target}")
