"""The joint-state stream between the client driver and the emulator, over loopback TCP."""

import time
from collections.abc import Callable

from hilrig.drivers.emulated.robot_state_server import EmulatedRobotStateServer
from hilrig.drivers.robot_state import RobotStateClient
from hilrig.drivers.robot_state_codec import MAGIC, RobotState, RobotStatus


def wait_until(condition: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("condition not reached")
        time.sleep(0.002)


def source(sequence: int) -> RobotState:
    q = 0.001 * (sequence % 1000)
    return RobotState(
        sequence, 1_000_000 * sequence, (q,) * 6, (0.0,) * 6, (0.5,) * 6, RobotStatus.ENABLED
    )


def test_frames_arrive_in_order_with_receive_times() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        wait_until(lambda: client.stats.frames >= 50)
        latest = client.latest()
        assert latest is not None
        assert latest.state == source(latest.state.sequence)
        staleness = client.staleness_ns()
        assert staleness is not None and staleness >= 0
    assert client.stats.crc_errors == client.stats.bytes_dropped == 0


def test_garbage_is_dropped_and_counted_and_the_stream_resumes() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        wait_until(lambda: client.stats.frames >= 5)
        server.inject(b"\xffjunk" + MAGIC + b"\x00" * 10)
        wait_until(lambda: client.stats.bytes_dropped >= 5)
        frames = client.stats.frames
        wait_until(lambda: client.stats.frames >= frames + 5)
    assert client.stats.bytes_dropped >= 5
    assert client.last_error is None


def test_a_stall_makes_the_state_stale_and_counts_the_gap() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        wait_until(lambda: client.stats.frames >= 5)
        server.stall(0.2)
        wait_until(lambda: (client.staleness_ns() or 0) > 50_000_000)
        gaps = client.stats.sequence_gaps
        wait_until(lambda: client.stats.sequence_gaps > gaps)
    assert client.stats.frames_missed >= 1


def test_the_client_reconnects_after_a_dropped_link() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port, backoff_s=(0.005, 0.05)) as client,
    ):
        wait_until(lambda: client.stats.frames >= 5)
        server.drop_links()
        wait_until(lambda: client.reconnects == 1 and client.connected)
        frames = client.stats.frames
        wait_until(lambda: client.stats.frames > frames + 5)
    assert server.stats.links_dropped == 1
    assert str(client.last_error).endswith("closed by the robot")
