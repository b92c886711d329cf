"""Drivers: the F/T emulator streaming at 1 kHz over a pty while the serial driver reads it.

The emulator runs in its own process (spawned); this process polls the driver (select on its
fd, then poll), as the rig's loop does. Each frame carries its slot number in Fx (kgf scale 1,
so the float is exact) and the emulator logs the monotonic time just before writing it; both
processes read the same system monotonic clock, so receive latency = driver receive time -
emulator write time. CPU is each process's user + system time over the streaming window
(os.times), as a share of one core.
Also timed: each stream's decode per frame (the compiled FtFrames and StateFrames against the
reference KunweiFramer and RobotStateDecoder, alternating in this process), the polled drivers per
call (FtSerial.poll with one frame waiting on a pty, RobotStateClient.poll with one frame waiting
on a loopback socket, JointTargetsWriter.write, and its poll taking one acknowledgement), gravity
compensation per call, and warm-started IK per tick.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import select
import socket
import tempfile
import time
from collections.abc import Callable
from functools import partial
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.harness import Result, quantiles_us
from benchmarks.settle import settle
from hilrig.drivers import FramerConfig, FtSerial, GravityCompensator, KunweiFramer, ToolLoad
from hilrig.drivers.ft.frames import FtFrames
from hilrig.drivers.ft.wire import encode_frame
from hilrig.drivers.joint_targets.link import JointTargetsWriter, ModbusEndpoint
from hilrig.drivers.robot_state.frames import StateFrames
from hilrig.drivers.robot_state.link import RobotStateClient
from hilrig.drivers.robot_state.wire import RobotState, RobotStateDecoder, RobotStatus, encode
from hilrig.emulator import EmulatorConfig, FtEmulator
from hilrig.robot import RobotModel

RATE_HZ = 1000.0
STREAM_S = 10.0
UNIT = FramerConfig(kgf_scale=1.0, max_abs_force_n=2.0**24)  # Fx carries the slot number
SLOTS = int((STREAM_S + 30.0) * RATE_HZ)


def slot_number(t_s: float) -> tuple[float, ...]:
    """Source of the benchmark: the frame's slot number in Fx (N, exact in float32)."""
    return (float(round(t_s * RATE_HZ) % 2**24), 0.0, 0.0, 0.0, 0.0, 0.0)


def emulator_process(port_path: str, pipe: Connection) -> None:
    """Child process: stream until told to stop, then send back write times, stats and CPU."""
    sent_ns = np.zeros(SLOTS, dtype=np.int64)

    def on_sent(t_s: float, t_ns: int) -> None:
        slot = round(t_s * RATE_HZ)
        if slot < SLOTS:
            sent_ns[slot] = t_ns

    config = EmulatorConfig(rate_hz=RATE_HZ, kgf_scale=1.0)
    with FtEmulator(slot_number, config=config, port_path=port_path, on_sent=on_sent) as emu:
        pipe.send("ready")
        pipe.recv()  # "start": the driver is about to connect
        cpu0, wall0 = cpu_s(), time.monotonic()
        pipe.recv()  # "stop"
        cpu1, wall1 = cpu_s(), time.monotonic()
        stats = emu.stats()
    pipe.send((sent_ns, stats, (cpu1 - cpu0) / (wall1 - wall0)))


def cpu_s() -> float:
    """User + system CPU time of this process so far, s."""
    times = os.times()
    return times.user + times.system


def bench_stream() -> list[Result]:
    ctx = mp.get_context("spawn")
    with tempfile.TemporaryDirectory(prefix="hilrig-bench-") as folder:
        port_path = str(Path(folder) / "ft")
        ours, theirs = ctx.Pipe()
        child = ctx.Process(target=emulator_process, args=(port_path, theirs), daemon=True)
        child.start()
        assert ours.recv() == "ready"
        ours.send("start")
        received: list[tuple[int, float]] = []
        with FtSerial(port_path, framer_config=UNIT) as ft:
            ft.poll(time.monotonic_ns())  # the frames read while connecting
            cpu0, wall0 = cpu_s(), time.monotonic()
            while time.monotonic() - wall0 < STREAM_S:
                select.select([ft.fileno()], [], [], 0.01)
                polled = ft.poll(time.monotonic_ns())
                slots = polled["wrench"][:, 0].tolist()
                received.extend(zip(polled["t_ns"].tolist(), slots, strict=True))
            cpu1, wall1 = cpu_s(), time.monotonic()
            status, framer = ft.status(), ft.framer_stats()
        ours.send("stop")
        sent_ns, emu_stats, emu_cpu = ours.recv()
        child.join(timeout=10)
    window_s = wall1 - wall0
    recv_ns = np.array([t for t, _ in received], dtype=np.int64)
    slots = np.array([int(fx) for _, fx in received], dtype=np.int64)
    latency_ns = recv_ns - sent_ns[slots]
    expected = int(slots[-1] - slots[0] + 1)
    lost = expected - len(slots)
    rate_hz = float((len(slots) - 1) / ((recv_ns[-1] - recv_ns[0]) / 1e9))
    q = quantiles_us(latency_ns)
    detail: dict[str, Any] = {
        "frames_received": len(slots),
        "frames_expected": expected,
        "window_s": round(window_s, 3),
        "driver_status": str(status),
        "framer": str(framer),
        "emulator": str(emu_stats),
        **{f"latency_{k}_us": round(v, 1) for k, v in q.items()},
    }
    driver_cpu = (cpu1 - cpu0) / window_s
    return [
        Result(
            "drivers", "F/T frame rate received", rate_hz, "Hz", ">= 990", rate_hz >= 990, detail
        ),
        Result("drivers", "F/T frames lost", lost, "frames", "", None, detail),
        Result("drivers", "F/T receive latency p50", q["p50"], "us", "", None, detail),
        Result("drivers", "F/T receive latency p99", q["p99"], "us", "<= 1000", q["p99"] <= 1000),
        Result("drivers", "F/T receive latency max", q["max"], "us", "", None),
        Result("drivers", "CPU emulator process", 100 * emu_cpu, "% core", "", None),
        Result("drivers", "CPU driver process", 100 * driver_cpu, "% core", "", None),
    ]


def _joint_frames(count: int) -> list[bytes]:
    """``count`` joint-state frames in sequence, as the robot streams them."""
    return [
        encode(RobotState(k, k, (1e-3 * k,) * 6, (0.1,) * 6, (2.0,) * 6, RobotStatus(3)))
        for k in range(count)
    ]


def bench_decoders(count: int = 20_000, rounds: int = 7) -> list[Result]:
    """Per frame, each stream's compiled decoder (into its rows) against its reference decoder
    (to tuples), alternating; medians of ``rounds`` runs each."""
    ft_frames = [encode_frame((float(k), 1.0, 2.0, 0.1, 0.2, 0.3)) for k in range(1000)]
    streams: tuple[tuple[str, list[bytes], dict[str, Callable[[bytes], object]]], ...] = (
        (
            "F/T framer per 28-byte frame",
            ft_frames,
            {"compiled": partial(FtFrames().feed_bytes, t_ns=0), "reference": KunweiFramer().feed},
        ),
        (
            "joint-state decode per 170-byte frame",
            _joint_frames(1000),
            {
                "compiled": partial(StateFrames().feed_bytes, t_ns=0),
                "reference": RobotStateDecoder().feed,
            },
        ),
    )
    out = []
    for name, frames, feeds in streams:
        for feed in feeds.values():
            feed(frames[0])  # the F/T framers lock on a frame and the next header
        times: dict[str, list[float]] = {"compiled": [], "reference": []}
        for _ in range(rounds):
            for kind, feed in feeds.items():
                start = time.perf_counter_ns()
                for k in range(count):
                    feed(frames[k % 1000])
                times[kind].append((time.perf_counter_ns() - start) / count / 1e3)
        fast, slow = float(np.median(times["compiled"])), float(np.median(times["reference"]))
        detail = {"reference_us": slow, "runs_us": times}
        out += [
            Result("drivers", f"{name}, compiled", fast, "us", "", None, detail),
            Result("drivers", "... time against the reference decoder", fast / slow, "x", "", None),
        ]
    return out


def bench_polled_calls(count: int = 5000) -> list[Result]:
    """Per call: F/T poll with one frame waiting, writer.write, writer.poll with one reply."""
    master, slave = os.openpty()
    ft = FtSerial(os.ttyname(slave))
    ft.connect(first_sample_timeout_s=None)
    frame, poll_ns = encode_frame((1.0, 2.0, 3.0, 0.1, 0.2, 0.3)), np.empty(count, np.int64)
    clock = time.perf_counter_ns
    os.write(master, frame + frame)  # the framer locks on a frame followed by a header
    while not len(ft.poll(time.monotonic_ns())):
        select.select([ft.fileno()], [], [], 1.0)
    for k in range(count):
        os.write(master, frame)
        got = 0
        while not got:  # the pty may hand the frame over in pieces: time the poll that frames it
            select.select([ft.fileno()], [], [], 1.0)
            start = clock()
            got = len(ft.poll(time.monotonic_ns()))
            poll_ns[k] = clock() - start
    ft.close()
    os.close(master)
    os.close(slave)
    state_ns = _time_state_polls(count)
    with socket.create_server(("127.0.0.1", 0)) as listener:
        writer = JointTargetsWriter(ModbusEndpoint(port=listener.getsockname()[1]))
        writer.connect(timeout_s=None)
        peer, _ = listener.accept()
        while not writer.is_connected:
            writer.poll(time.monotonic_ns())
        ack = bytes(writer._ack)
        q, write_ns, reply_ns = np.zeros(6), np.empty(count, np.int64), np.empty(count, np.int64)
        with peer:
            for k in range(count):
                q[0] = 1e-4 * k
                start = clock()
                writer.write(q)
                write_ns[k] = clock() - start
                peer.recv(64)
                peer.sendall(ack)
                select.select([writer.fileno()], [], [], 1.0)
                start = clock()
                writer.poll(time.monotonic_ns())
                reply_ns[k] = clock() - start
        assert writer.stats.written == count and writer.errors == 0
        writer.close()
    out = []
    for name, samples in (
        ("FtSerial.poll, one frame waiting", poll_ns),
        ("RobotStateClient.poll, one frame waiting", state_ns),
        ("JointTargetsWriter.write (sent at once)", write_ns),
        ("JointTargetsWriter.poll, one acknowledgement", reply_ns),
    ):
        q_us = quantiles_us(samples)
        out.append(Result("drivers", f"{name} p50", q_us["p50"], "us", "", None, q_us))
    return out


def _time_state_polls(count: int) -> np.ndarray:
    """RobotStateClient.poll with one frame waiting on a loopback socket, ``count`` times (ns)."""
    frames, poll_ns, clock = (
        _joint_frames(count + 1),
        np.empty(count, np.int64),
        time.perf_counter_ns,
    )
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = RobotStateClient("127.0.0.1", listener.getsockname()[1])
        client.connect(first_frame_timeout_s=None)
        peer, _ = listener.accept()
        with peer:
            peer.sendall(frames[0])
            while not len(client.poll(time.monotonic_ns())):
                select.select([client.fileno()], [], [], 1.0)
            for k in range(count):
                peer.sendall(frames[k + 1])
                got = 0
                while not got:  # a frame may come in pieces: time the poll that completes it
                    select.select([client.fileno()], [], [], 1.0)
                    start = clock()
                    got = len(client.poll(time.monotonic_ns()))
                    poll_ns[k] = clock() - start
        assert client.decoder_stats().frames == count + 1 and client.errors == 0
        client.close()
    return poll_ns


def bench_compensation() -> list[Result]:
    compensator = GravityCompensator(ToolLoad(1.0, (0.0, 0.01, 0.06)))
    wrench, rotation, out = np.ones(6), np.eye(3), np.empty(6)
    count = 100_000
    start = time.perf_counter_ns()
    for _ in range(count):
        compensator.compensate(wrench, rotation, out)
    per_call_us = (time.perf_counter_ns() - start) / count / 1e3
    return [Result("drivers", "gravity compensation per call", per_call_us, "us", "", None)]


def bench_ik() -> list[Result]:
    """IK every 1 ms tick along a joint-space swing (up to 1.8 rad/s), warm-started."""
    model = RobotModel()
    centre = np.array([0.1, -0.5, 1.2, 0.3, 1.0, 0.2])
    rates = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    ticks = 20_000
    poses = [model.fk(centre + 0.3 * np.sin(rates * k * 1e-3)) for k in range(ticks)]
    q = model.ik(poses[0], centre, max_iterations=50).q_rad
    times_ns = np.empty(ticks, dtype=np.int64)
    iterations = np.empty(ticks, dtype=np.int64)
    unconverged = 0
    clock = time.perf_counter_ns
    for k, pose in enumerate(poses):
        start = clock()
        result = model.ik(pose, q, max_iterations=5)
        times_ns[k] = clock() - start
        q = result.q_rad
        iterations[k] = result.iterations
        unconverged += not result.converged
    q_us = quantiles_us(times_ns)
    detail = {
        "ticks": ticks,
        "unconverged": unconverged,
        "iterations_histogram": np.bincount(iterations).tolist(),
        **{f"{k}_us": round(v, 2) for k, v in q_us.items()},
    }
    return [
        Result("drivers", "IK per tick mean (warm start)", q_us["mean"], "us", "", None, detail),
        Result("drivers", "IK per tick p99", q_us["p99"], "us", "<= 100", q_us["p99"] <= 100),
        Result(
            "drivers", "IK iterations mean", float(iterations.mean()), "steps", "", None, detail
        ),
        Result("drivers", "IK unconverged ticks", unconverged, "ticks", "== 0", unconverged == 0),
    ]


def run() -> list[Result]:
    settled = settle("drivers")  # the stream's rate and latency, on a quiet machine
    return [
        settled,
        *bench_stream(),
        *bench_decoders(),
        *bench_polled_calls(),
        *bench_compensation(),
        *bench_ik(),
    ]
