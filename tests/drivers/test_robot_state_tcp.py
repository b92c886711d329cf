"""The joint-state stream between the client driver and the emulator, over loopback TCP."""

from waiting import wait_until

from hilrig.drivers.emulated.robot_state_server import EmulatedRobotStateServer
from hilrig.drivers.robot_state import RobotStateClient
from hilrig.drivers.robot_state_codec import MAGIC, RobotState, RobotStatus
from hilrig.errors import LinkError


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
        wait_until(lambda: client.decoder_stats().frames >= 50)
        latest = client.latest()
        assert latest is not None
        assert latest.state == source(latest.state.sequence)
        status = client.status()
        assert status.connected and status.age_ns is not None and status.age_ns >= 0
    assert client.decoder_stats().crc_errors == client.decoder_stats().bytes_dropped == 0


def test_garbage_is_dropped_and_counted_and_the_stream_resumes() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        wait_until(lambda: client.decoder_stats().frames >= 5)
        server.inject(b"\xffjunk" + MAGIC + b"\x00" * 10)
        wait_until(lambda: client.decoder_stats().bytes_dropped >= 5)
        frames = client.decoder_stats().frames
        wait_until(lambda: client.decoder_stats().frames >= frames + 5)
    assert client.decoder_stats().bytes_dropped >= 5
    assert client.last_error == ""


def test_a_stall_makes_the_state_stale_and_counts_the_gap() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        wait_until(lambda: client.decoder_stats().frames >= 5)
        server.stall(0.2)
        wait_until(lambda: (client.status().age_ns or 0) > 50_000_000)
        gaps = client.decoder_stats().sequence_gaps
        wait_until(lambda: client.decoder_stats().sequence_gaps > gaps)
    assert client.decoder_stats().frames_missed >= 1
    assert client.stalls == 1


def test_the_client_reconnects_after_a_dropped_link() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port, backoff_s=(0.005, 0.05)) as client,
    ):
        wait_until(lambda: client.decoder_stats().frames >= 5)
        server.drop_links()
        wait_until(lambda: client.reconnects == 1 and client.is_connected)
        frames = client.decoder_stats().frames
        wait_until(lambda: client.decoder_stats().frames > frames + 5)
    assert server.stats.links_dropped == 1
    assert client.last_error.endswith("closed by the robot")
    assert client.stalls == 0 and client.errors == 1


def test_connect_fails_clearly_when_no_robot_answers() -> None:
    with EmulatedRobotStateServer(source) as server:
        port = server.port
    client = RobotStateClient("127.0.0.1", port)
    try:
        client.connect(first_frame_timeout_s=0.2)
    except LinkError as err:
        assert str(err).startswith(
            f"robot state tcp://127.0.0.1:{port}: no valid frame within 0.2 s ("
        )
    else:
        raise AssertionError("no error")
    assert not client.is_connected
