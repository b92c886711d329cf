"""The emulated rig in its own process at 1 kHz while a client reads and writes at 1 kHz.

The rig runs as the sessions run it (:class:`RigProcess`); this process is a client with a
session's traffic, through :class:`RigProbe` (plain wire clients, no hilrig driver): it sleeps
until the F/T pty has data or the 1 ms deadline passes, reads both streams without blocking,
and sends one Modbus joint-target write (pymodbus-framed) whose acknowledgement it collects at a
later wake-up, as the session's loop does, for ``DURATION_S``. Measured: the rig process's CPU
(utime + stime from /proc over wall time; target <= 25 % of a core), frames received against the
rig's own sent counters, joint-state receive latency (the emulated controller stamps frames with
the host monotonic clock) and the time from a write's request to the wake-up that collected its
acknowledgement. Then the same for ``SYNC_S`` with a client that waits for each reply (pymodbus's
synchronous client): a reply that wakes a waiting reader costs the rig more, reported beside.
``python -m benchmarks.bench_rig`` prints them.
"""

from __future__ import annotations

import os
import time
from collections import deque
from pathlib import Path

from benchmarks.harness import Result, quantiles_us
from benchmarks.settle import settle
from hilrig.emulator.probe import RigProbe
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.rig.rig_process import RigProcess

DURATION_S = 10.0
SYNC_S = 5.0
TICK_NS = 1_000_000
CPU_TARGET_PERCENT = 25.0
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def run() -> list[Result]:
    settled = settle("rig")
    rig = RigProcess("paper-end-effector")
    endpoints = rig.start()
    try:
        assert rig.pid is not None
        with RigProbe(endpoints) as probe:
            return [settled, *measure(rig, rig.pid, probe), *measure_sync(rig.pid, probe)]
    finally:
        rig.stop()


def measure(rig: RigProcess, pid: int, probe: RigProbe) -> list[Result]:
    """Drive the rig for DURATION_S through ``probe`` as a session does; the results."""
    deadline = time.monotonic() + 0.5  # settle: connections, first frames
    while time.monotonic() < deadline:
        probe.read(0.01)
    latencies_ns: list[int] = []
    ack_ns: list[int] = []
    unacked: deque[int] = deque()  # send times of the writes not yet acknowledged
    ft_received = state_received = writes = 0
    q = HOME_Q_RAD
    before = rig.counters()
    rig_cpu0, own_cpu0 = cpu_s(pid), cpu_s(os.getpid())
    start = tick = time.monotonic_ns()
    while tick - start < DURATION_S * 1e9:
        tick += TICK_NS
        probe.wait_for_ft(max(0, tick - time.monotonic_ns()) / 1e9)
        samples, states = probe.read()
        now = time.monotonic_ns()
        ft_received += len(samples)
        state_received += len(states)
        latencies_ns += [now - state.device_t_ns for state in states]
        ack_ns += [now - unacked.popleft() for _ in probe.acks()]
        writes += 1
        unacked.append(time.monotonic_ns())
        probe.send(q, writes)
    elapsed_s = (time.monotonic_ns() - start) / 1e9
    rig_cpu = (cpu_s(pid) - rig_cpu0) / elapsed_s * 100
    own_cpu = (cpu_s(os.getpid()) - own_cpu0) / elapsed_s * 100
    after = rig.counters()
    ft_sent = after.ft_frames_sent - before.ft_frames_sent
    state_sent = after.joint_frames_sent - before.joint_frames_sent
    state_q, ack_q = quantiles_us(latencies_ns), quantiles_us(ack_ns)
    detail = {
        "duration_s": elapsed_s,
        "state_latency_us": state_q,
        "ack_latency_us": ack_q,
        "writes_sent": writes,
        "acks_collected": len(ack_ns),
        "rig_counters": after.__dict__,
        "ft_frames_sent": ft_sent,
        "joint_frames_sent": state_sent,
    }
    ft_rate, state_rate = ft_received / elapsed_s, state_received / elapsed_s
    applied = after.modbus_writes - before.modbus_writes
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
        Result("rig", "Modbus writes applied", applied / elapsed_s, "Hz", "", None, detail),
        Result("rig", "Modbus request to ack collected p50", ack_q["p50"], "us", "", None, detail),
        Result("rig", "Modbus request to ack collected p99", ack_q["p99"], "us", "", None, detail),
        Result("rig", "CPU, client process", own_cpu, "% of a core", "", None, detail),
    ]


def measure_sync(pid: int, probe: RigProbe) -> list[Result]:
    """The rig's CPU for SYNC_S with a client that waits for every reply (pymodbus's
    synchronous client), each write answered before the next."""
    rig_cpu0 = cpu_s(pid)
    round_trips_ns: list[int] = []
    start = tick = time.monotonic_ns()
    while tick - start < SYNC_S * 1e9:
        tick += TICK_NS
        time.sleep(max(0, tick - time.monotonic_ns()) / 1e9)
        probe.read()
        sent_ns = time.monotonic_ns()
        probe.write(HOME_Q_RAD, len(round_trips_ns) + 1)
        round_trips_ns.append(time.monotonic_ns() - sent_ns)
    elapsed_s = (time.monotonic_ns() - start) / 1e9
    rig_cpu = (cpu_s(pid) - rig_cpu0) / elapsed_s * 100
    detail = {"duration_s": elapsed_s, "round_trip_us": quantiles_us(round_trips_ns)}
    return [
        Result(
            "rig",
            "CPU, emulated rig process, waiting client",
            rig_cpu,
            "% of a core",
            "",
            None,
            detail,
        ),
        Result(
            "rig",
            "Modbus write round trip p50, waiting client",
            detail["round_trip_us"]["p50"],
            "us",
            "",
            None,
            detail,
        ),
    ]


if __name__ == "__main__":
    for result in run():
        print(f"{result.name}: {result.value:.1f} {result.unit} {result.target}")
