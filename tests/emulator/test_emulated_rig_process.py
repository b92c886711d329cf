"""The emulated rig in its own process, read through plain wire clients: exact counts.

Every frame the rig reports sent is received, every write it reports applied was acknowledged;
faults from the parent change what arrives. Waits poll a count with a generous deadline; nothing
asserts a time or a rate.
"""

import os
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
from pymodbus.constants import ExcCodes

from hilrig.drivers.ft.wire import FtSample
from hilrig.drivers.robot_state.wire import RobotState
from hilrig.emulator.probe import RigProbe
from hilrig.emulator.rig import HOME_Q_RAD, RigEndpoints
from hilrig.rig.rig_process import RigCounters, RigProcess

DEADLINE_S = 30.0


class Received:
    """What a probe has read so far."""

    def __init__(self, probe: RigProbe) -> None:
        self.probe = probe
        self.samples: list[FtSample] = []
        self.states: list[RobotState] = []

    def read_until(self, condition: Callable[[], bool]) -> None:
        deadline = time.monotonic() + DEADLINE_S
        while not condition():
            assert time.monotonic() < deadline, "condition not reached"
            samples, states = self.probe.read(0.01)
            self.samples += samples
            self.states += states


@pytest.fixture
def rig() -> Iterator[tuple[RigProcess, RigEndpoints]]:
    process = RigProcess("none")
    endpoints = process.start()
    yield process, endpoints
    process.stop()


def test_every_frame_sent_is_received_and_every_write_applied(
    rig: tuple[RigProcess, RigEndpoints],
) -> None:
    process, endpoints = rig
    with RigProbe(endpoints) as probe:
        got = Received(probe)
        got.read_until(lambda: len(got.samples) >= 200 and len(got.states) >= 200)
        replies = [probe.write(np.asarray(HOME_Q_RAD) + 0.01, n) for n in range(1, 51)]
        assert not any(reply.isError() for reply in replies)
        probe.stop_ft()
        got.read_until(lambda: process.counters().ft_stops == 1)
        ft_sent = process.counters().ft_frames_sent
        got.read_until(lambda: len(got.samples) >= ft_sent)
        final = process.stop()
        got.read_until(lambda: probe.joint_closed)  # the rig closed the stream: all is in
    assert isinstance(final, RigCounters) and final == process.final_counters
    assert final.ft_frames_sent == ft_sent == len(got.samples)
    assert final.ft_frames_dropped == 0 and final.ft_starts == final.ft_stops == 1
    assert final.joint_frames_sent == len(got.states) and final.joint_frames_dropped == 0
    sequences = [s.sequence for s in got.states]
    assert sequences == sorted(sequences)
    assert final.modbus_writes == 50 and final.modbus_exceptions_sent == 0
    assert got.probe.ft_framer.stats.frames_rejected == 0
    assert got.probe.state_decoder.stats.crc_errors == 0


def test_faults_from_the_parent_reach_the_wire(rig: tuple[RigProcess, RigEndpoints]) -> None:
    process, endpoints = rig
    with RigProbe(endpoints) as probe:
        got = Received(probe)
        got.read_until(lambda: len(got.samples) >= 10 and len(got.states) >= 10)
        process.fault("modbus.inject_exceptions", 2, ExcCodes.DEVICE_BUSY)
        codes = [probe.write(HOME_Q_RAD, n) for n in range(1, 4)]
        assert [getattr(reply, "exception_code", 0) for reply in codes] == [6, 6, 0]
        process.fault("ft.bad_values", 3)
        rejected = probe.ft_framer.stats.frames_rejected
        got.read_until(lambda: probe.ft_framer.stats.frames_rejected == rejected + 3)
        process.fault("ft.stall", 0.05)
        got.read_until(lambda: process.counters().ft_slots_skipped >= 10)
        process.fault("robot_state.drop_links", 0.0)
        got.read_until(lambda: probe.joint_closed)
        pty = os.path.realpath(endpoints.ft_wrist_port)
        process.fault("ft.drop_link", 0.05)
        deadline = time.monotonic() + DEADLINE_S
        while pty_behind(endpoints.ft_wrist_port) in (pty, endpoints.ft_wrist_port):
            assert time.monotonic() < deadline, "no new pty"
            time.sleep(0.01)  # a new pty behind the same path
        counters = process.counters()
    assert counters.modbus_writes == 1 and counters.modbus_exceptions_sent == 2
    assert counters.slots >= counters.joint_ticks > 0


def pty_behind(link: str) -> str:
    """The pty the port's path leads to; the path itself while the link is being replaced (a
    resolution that meets the old link gone raises, which a slow machine made happen)."""
    try:
        return os.path.realpath(link)
    except FileNotFoundError:
        return link
