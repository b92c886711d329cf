"""The polled serial F/T driver against the emulated sensor over a real pty: protocol and faults.

No mocks: the emulator writes the wire bytes to a pty master, the driver reads the slave from
the test thread (select on ``fileno()``, then ``poll``). Waits poll until a count is reached,
with a generous deadline; nothing asserts on timing.
"""

import contextlib
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from polling import poll_for, poll_until
from waiting import wait_until

from hilrig.drivers import FtSerial, GravityCompensator, ToolLoad
from hilrig.drivers.ft.wire import START_COMMAND
from hilrig.emulator import EmulatorConfig, FtEmulator
from hilrig.errors import LinkError

WRENCH = (1.5, -2.0, 10.0, 0.25, -0.125, 0.05)
FAST_BACKOFF = (0.01, 0.05)


def constant(t_s: float) -> tuple[float, ...]:
    return WRENCH


@pytest.fixture
def thread_errors() -> Iterator[list[threading.ExceptHookArgs]]:
    """Fails the test if any exception escapes any thread (the emulator's)."""
    seen: list[threading.ExceptHookArgs] = []
    previous = threading.excepthook
    threading.excepthook = seen.append
    yield seen
    threading.excepthook = previous
    assert not seen, f"exception escaped a thread: {seen[0].exc_value!r}"


@pytest.fixture
def emulator(thread_errors: list[threading.ExceptHookArgs]) -> Iterator[FtEmulator]:
    with FtEmulator(constant) as emu:
        yield emu


@pytest.fixture
def sensor(emulator: FtEmulator) -> Iterator[FtSerial]:
    # a stall limit well above any scheduling hiccup of a loaded test machine
    with FtSerial(str(emulator.port_path), backoff_s=FAST_BACKOFF, stall_after_s=0.1) as ft:
        yield ft


def samples_after(ft: FtSerial, count: int) -> list[Any]:
    """Polls until ``count`` more samples arrived; returns (copies of) every sample polled
    meanwhile, rows of SAMPLE_DTYPE."""
    target = ft.status().samples + count
    polled: list[Any] = []
    poll_until(lambda: ft.status().samples >= target, ft, sink=polled)
    return polled


def test_stream_starts_on_the_start_command_and_stops_on_stop(emulator: FtEmulator) -> None:
    time.sleep(0.05)
    assert emulator.stats().frames_sent == 0  # the sensor waits for the start command
    with FtSerial(str(emulator.port_path)) as ft:
        assert ft.is_connected and ft.fileno() >= 0
        wait_until(lambda: emulator.stats().starts == 1)
    assert ft.fileno() == -1
    wait_until(lambda: emulator.stats().stops == 1)
    assert not emulator.stats().streaming


def test_samples_round_trip_in_si_units_stamped_with_the_poll_time(sensor: FtSerial) -> None:
    samples_after(sensor, 20)
    now_ns = time.monotonic_ns()
    poll_until(lambda: len(sensor.poll(now_ns)) > 0, timeout_s=5)
    sample = sensor.latest()
    assert sample is not None
    assert sample["wrench"].tolist() == pytest.approx(WRENCH, rel=1e-6)
    assert sample["t_ns"] == now_ns
    status = sensor.status()
    assert status.connected and status.errors == 0 and status.age_ns is not None


def test_polls_return_every_sample_in_order_from_the_first(sensor: FtSerial) -> None:
    polled = samples_after(sensor, 50)
    assert [s["seq"] for s in polled] == list(range(len(polled)))  # connect's first included
    assert sensor.status().samples == len(polled)
    assert [s["t_ns"] for s in polled] == sorted(s["t_ns"] for s in polled)


def test_no_thread_runs_while_polling(emulator: FtEmulator) -> None:
    before = threading.active_count()
    with FtSerial(str(emulator.port_path)) as ft:
        for _ in range(5):
            samples_after(ft, 20)
            assert threading.active_count() == before


def test_garbage_is_detected_counted_and_recovered(emulator: FtEmulator, sensor: FtSerial) -> None:
    samples_after(sensor, 10)
    garbage = b"\x48\xaa\x0d" + os.urandom(200) + b"\x48\xaa"
    emulator.inject_garbage(garbage)
    samples_after(sensor, 20)
    stats = sensor.framer_stats()
    assert stats.resyncs >= 1 and stats.bytes_dropped >= len(garbage) and stats.locked
    latest = sensor.latest()
    assert latest is not None and latest["wrench"].tolist() == pytest.approx(WRENCH, rel=1e-6)


def test_split_frames_lose_nothing(emulator: FtEmulator, sensor: FtSerial) -> None:
    samples_after(sensor, 10)
    emulator.split_frames(50)
    poll_until(lambda: emulator.stats().split_frames == 50, sensor)
    samples_after(sensor, 5)
    stats = sensor.framer_stats()
    assert stats.resyncs == 0 and stats.bytes_dropped == 0 and stats.frames_rejected == 0


def test_header_bytes_inside_floats_do_not_break_sync(
    emulator: FtEmulator, sensor: FtSerial
) -> None:
    samples_after(sensor, 10)
    emulator.header_in_floats(50)
    poll_until(lambda: emulator.stats().header_frames == 50, sensor)
    samples_after(sensor, 5)
    stats = sensor.framer_stats()
    assert stats.resyncs == 0 and stats.bytes_dropped == 0 and stats.frames_rejected == 0


def test_bad_values_are_rejected_and_counted(emulator: FtEmulator, sensor: FtSerial) -> None:
    samples_after(sensor, 10)
    emulator.bad_values(3)
    poll_until(lambda: emulator.stats().bad_value_frames == 3, sensor)
    samples_after(sensor, 5)
    assert sensor.framer_stats().frames_rejected == 3
    assert sensor.framer_stats().resyncs == 0


def test_stall_is_detected_counted_and_recovered(emulator: FtEmulator, sensor: FtSerial) -> None:
    samples_after(sensor, 10)
    emulator.stall(0.3)
    poll_until(lambda: sensor.status().stalls == 1, sensor)
    samples_after(sensor, 20)
    assert sensor.status().stalls == 1 and sensor.status().reconnects == 0


def test_the_start_command_is_resent_after_a_silence() -> None:
    master, slave = os.openpty()
    try:
        os.set_blocking(master, False)
        ft = FtSerial(os.ttyname(slave), restart_after_s=0.05)
        ft.connect(first_sample_timeout_s=None)
        received = b""
        while received.count(START_COMMAND) < 3:
            poll_for(0.02, ft)
            with contextlib.suppress(BlockingIOError):
                received += os.read(master, 64)
        ft.close()
        assert set(received.split(START_COMMAND)) == {b""}  # nothing but start commands
        assert ft.status().samples == ft.status().errors == 0
    finally:
        os.close(master)
        os.close(slave)


def test_link_drop_is_detected_and_the_driver_reconnects_and_restarts(
    emulator: FtEmulator, sensor: FtSerial
) -> None:
    samples_after(sensor, 10)
    emulator.drop_link(0.1)
    poll_until(lambda: sensor.status().reconnects == 1, sensor)
    samples_after(sensor, 20)
    status = sensor.status()
    assert status.errors >= 1 and status.last_error  # the lost link was recorded
    assert emulator.stats().link_drops == 1 and emulator.stats().starts == 2


def test_no_exception_escapes_poll(sensor: FtSerial, monkeypatch: pytest.MonkeyPatch) -> None:
    samples_after(sensor, 5)
    framer = sensor._framer
    real_receive = framer.receive
    calls = iter(range(10**9))

    def failing_once(fd: int, t_ns: int) -> int:
        if next(calls) == 0:
            raise RuntimeError("bug in the framer")
        return real_receive(fd, t_ns)

    monkeypatch.setattr(framer, "receive", failing_once)
    poll_until(lambda: sensor.status().errors == 1, sensor)
    samples_after(sensor, 20)  # poll reopened the port and reads on
    assert sensor.status().last_error == "RuntimeError: bug in the framer"
    assert sensor.status().reconnects == 1


def test_connect_to_a_missing_port_raises_link_error(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-tty"
    with pytest.raises(LinkError, match=re.escape(f"F/T sensor {missing}: cannot open")):
        FtSerial(str(missing)).connect()


def test_connect_to_a_silent_port_raises_link_error() -> None:
    master, slave = os.openpty()
    try:
        ft = FtSerial(os.ttyname(slave))
        with pytest.raises(LinkError, match=r"no valid frame within 0\.2 s"):
            ft.connect(first_sample_timeout_s=0.2)
        assert os.read(master, 64).startswith(START_COMMAND)  # it did ask for data
        assert not ft.is_connected and ft.fileno() == -1
    finally:
        os.close(master)
        os.close(slave)


def test_reconnect_after_close(emulator: FtEmulator) -> None:
    ft = FtSerial(str(emulator.port_path))
    for _ in range(2):
        ft.connect()
        samples_after(ft, 5)
        ft.close()
        assert not ft.is_connected
        assert len(ft.poll(time.monotonic_ns())) == 0  # closed: poll does not reopen
    assert emulator.stats().starts == 2


def test_tare_and_gravity_compensation_end_to_end(
    thread_errors: list[threading.ExceptHookArgs],
) -> None:
    tool = ToolLoad(0.8, (0.0, 0.01, 0.05))
    pose = {"r": np.eye(3)}
    tilted = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # 90 deg about x
    config = EmulatorConfig(bias_in_sensor=(0.3, -0.2, 1.0, 0.01, 0.02, -0.03), tool=tool)
    with (
        FtEmulator(config=config, orientation=lambda t_s: pose["r"]) as emu,
        FtSerial(str(emu.port_path)) as ft,
    ):
        recorded: list[Any] = []
        compensator = GravityCompensator(tool)
        compensator.tare(ft.average(0.05, on_sample=recorded.append), np.eye(3))
        assert [s["seq"] for s in recorded] == list(range(len(recorded)))  # from the first one
        pose["r"] = tilted
        samples_after(ft, 5)  # drop samples taken before the new pose reached the sensor
        raw = ft.average(0.05)
        assert np.max(np.abs(raw - config.bias_in_sensor)) > 1.0  # gravity moved the reading
        np.testing.assert_allclose(compensator.compensate(raw, tilted), 0.0, atol=1e-5)


def test_average_without_samples_raises_link_error() -> None:
    master, slave = os.openpty()
    try:
        ft = FtSerial(os.ttyname(slave))
        ft.connect(first_sample_timeout_s=None)
        with pytest.raises(LinkError, match=re.escape(f"F/T sensor {ft.port}: no samples")):
            ft.average(0.01, timeout_s=0.05)
        ft.close()
    finally:
        os.close(master)
        os.close(slave)


def test_emulator_runs_as_its_own_process(tmp_path: Path) -> None:
    port_path = tmp_path / "ft"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hilrig.emulator.ft_emulator",
            "--port-path",
            str(port_path),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        assert str(port_path) in process.stdout.readline()
        with FtSerial(str(port_path)) as ft:
            samples_after(ft, 10)
            latest = ft.latest()
            assert latest is not None and latest["wrench"].tolist() == [0.0] * 6
    finally:
        process.terminate()
        assert process.wait(timeout=5) == 0
    assert not port_path.exists()
