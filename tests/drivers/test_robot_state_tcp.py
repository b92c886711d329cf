"""The polled joint-state client against the emulated stream over loopback TCP.

The client is driven from the test thread (select on ``fileno()``, then ``poll``) until a count
is reached, with a generous deadline; nothing asserts on timing.
"""

import socket
import struct
import threading
import time
from typing import Any

import numpy as np
from polling import poll_for, poll_until
from state_rows import as_state

from hilrig.drivers.robot_state.link import RobotStateClient
from hilrig.drivers.robot_state.wire import (
    FRAME_BYTES,
    MAGIC,
    STATE_DTYPE,
    DecoderStats,
    RobotState,
    RobotStateDecoder,
    RobotStatus,
    encode,
)
from hilrig.emulator.robot_state_server import EmulatedRobotStateServer
from hilrig.errors import LinkError


def source(sequence: int) -> RobotState:
    q = 0.001 * (sequence % 1000)
    return RobotState(
        sequence, 1_000_000 * sequence, (q,) * 6, (0.0,) * 6, (0.5,) * 6, RobotStatus.ENABLED
    )


def test_frames_arrive_in_order_stamped_with_the_poll_time() -> None:
    received: list[Any] = []
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        poll_until(lambda: len(received) >= 50, client, sink=received)
        states = [as_state(r) for r in received]
        sequences = [s.sequence for s in states]
        assert sequences == list(range(sequences[0], sequences[0] + len(received)))
        assert states == [source(n) for n in sequences]
        latest = client.latest()
        assert latest is not None and latest.tobytes() == received[-1].tobytes()
        assert client.decoder_stats().frames == len(received)  # connect's frames included
        assert client.status().samples == len(received)
        now_ns = time.monotonic_ns()
        poll_until(lambda: len(client.poll(now_ns)) > 0)
        latest = client.latest()
        assert latest is not None and latest["t_ns"] == now_ns
        status = client.status()
        assert status.connected and status.age_ns is not None and status.age_ns >= 0
    assert client.decoder_stats().crc_errors == client.decoder_stats().bytes_dropped == 0
    assert client.fileno() == -1 and not client.is_connected


def test_no_thread_runs_while_polling() -> None:
    with EmulatedRobotStateServer(source) as server:
        before = threading.active_count()
        with RobotStateClient("127.0.0.1", server.port) as client:
            for n in range(5):
                poll_until(lambda n=n: client.decoder_stats().frames >= 20 * (n + 1), client)
                assert threading.active_count() == before


def test_garbage_is_dropped_and_counted_and_the_stream_resumes() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port) as client,
    ):
        poll_until(lambda: client.decoder_stats().frames >= 5, client)
        server.inject(b"\xffjunk" + MAGIC + b"\x00" * 10)
        poll_until(lambda: client.decoder_stats().bytes_dropped >= 5, client)
        frames = client.decoder_stats().frames
        poll_until(lambda: client.decoder_stats().frames >= frames + 5, client)
    assert client.decoder_stats().bytes_dropped >= 5
    assert client.last_error == "" and client.errors == 0


def test_a_stall_makes_the_state_stale_and_counts_the_gap() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port, stall_after_s=0.1) as client,
    ):
        poll_until(lambda: client.decoder_stats().frames >= 5, client)
        server.stall(0.3)
        poll_until(lambda: (client.status().age_ns or 0) > 100_000_000, client)
        gaps = client.decoder_stats().sequence_gaps
        poll_until(lambda: client.decoder_stats().sequence_gaps > gaps, client)
    assert client.decoder_stats().frames_missed >= 1
    assert client.stalls == 1


def test_the_client_reconnects_after_a_dropped_link() -> None:
    with (
        EmulatedRobotStateServer(source) as server,
        RobotStateClient("127.0.0.1", server.port, backoff_s=(0.005, 0.05)) as client,
    ):
        poll_until(lambda: client.decoder_stats().frames >= 5, client)
        server.drop_links()
        poll_until(lambda: client.reconnects == 1 and client.is_connected, client)
        frames = client.decoder_stats().frames
        poll_until(lambda: client.decoder_stats().frames > frames + 5, client)
    assert server.stats.links_dropped == 1
    assert client.last_error == f"robot state tcp://127.0.0.1:{server.port}: closed by the robot"
    assert client.stalls == 0 and client.errors == 1


def test_connect_without_waiting_keeps_trying_until_the_robot_listens() -> None:
    with EmulatedRobotStateServer(source) as server:
        port = server.port
    client = RobotStateClient("127.0.0.1", port, backoff_s=(0.005, 0.02))
    client.connect(first_frame_timeout_s=None)
    poll_until(lambda: client.errors >= 3, client)  # refused, counted, retried with backoff
    assert not client.is_connected and client.fileno() == -1
    assert client.last_error == "TCP connect failed: Connection refused"
    with EmulatedRobotStateServer(source, port=port):
        poll_until(lambda: client.decoder_stats().frames >= 5, client)
        assert client.is_connected and client.reconnects == 0  # the first link, not a reconnect
    client.close()


def test_frames_split_across_polls_are_reassembled() -> None:
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = RobotStateClient("127.0.0.1", listener.getsockname()[1])
        client.connect(first_frame_timeout_s=None)
        peer, _ = listener.accept()
        with peer:
            received: list[Any] = []
            frames = b"".join(encode(source(n)) for n in range(3))
            for at in range(0, len(frames), 7):  # 7-byte pieces, each polled on its own
                peer.sendall(frames[at : at + 7])
                poll_until(
                    lambda at=at: client.bytes_received >= min(at + 7, len(frames)),
                    client,
                    sink=received,
                )
            assert [as_state(r) for r in received] == [source(n) for n in range(3)]
            poll_for(0.02, client)
            assert client.errors == 0
        client.close()


def test_connect_fails_clearly_when_no_robot_answers() -> None:
    with EmulatedRobotStateServer(source) as server:
        port = server.port
    client = RobotStateClient("127.0.0.1", port)
    try:
        client.connect(first_frame_timeout_s=0.2)
    except LinkError as err:
        assert str(err) == (
            f"robot state tcp://127.0.0.1:{port}: no valid frame within 0.2 s "
            "(TCP connect failed: Connection refused)"
        )
    else:
        raise AssertionError("no error")
    assert not client.is_connected


class PythonRows:
    """A decoder in plain Python (the shape a real controller's format plugs in with): the
    reference decoder's frames as rows of STATE_DTYPE."""

    def __init__(self) -> None:
        self._decoder = RobotStateDecoder()
        self._buffer = bytearray(4096)
        self.rows = np.zeros(64, dtype=STATE_DTYPE)
        self.newest = np.zeros(1, dtype=STATE_DTYPE)

    @property
    def free(self) -> memoryview:
        return memoryview(self._buffer)

    def feed(self, count: int, t_ns: int) -> int:
        frames = self._decoder.feed(bytes(self._buffer[:count]))
        for n, frame in enumerate(frames):
            self.rows[n] = (
                t_ns,
                frame.device_t_ns,
                frame.sequence,
                frame.q_rad,
                frame.qd_rad_s,
                frame.torque_nm,
                int(frame.status),
            )
        if frames:
            self.newest[0] = self.rows[len(frames) - 1]
        return len(frames)

    @property
    def stats(self) -> DecoderStats:
        return self._decoder.stats

    def reset(self) -> None:
        self._decoder = RobotStateDecoder()


def test_a_decoder_in_python_plugs_in_through_free_and_feed() -> None:
    received: list[Any] = []
    with EmulatedRobotStateServer(source) as server:
        client = RobotStateClient("127.0.0.1", server.port, decoder_factory=PythonRows)
        with client:
            poll_until(lambda: len(received) >= 20, client, sink=received)
            states = [as_state(r) for r in received]
            assert states == [source(s.sequence) for s in states]
            assert client.bytes_received >= FRAME_BYTES * 20
            assert client.latest_t_ns == int(received[-1]["t_ns"])
            server.drop_links()
            poll_until(lambda: client.errors == 1, client)
    assert client.last_error == f"robot state tcp://127.0.0.1:{server.port}: closed by the robot"


def test_a_reset_link_is_counted_with_the_system_s_error() -> None:
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = RobotStateClient("127.0.0.1", listener.getsockname()[1], backoff_s=(10, 10))
        client.connect(first_frame_timeout_s=None)
        peer, _ = listener.accept()
        received: list[Any] = []
        peer.sendall(encode(source(1)))
        poll_until(lambda: len(received) == 1, client, sink=received)
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        peer.close()  # with a zero linger: a reset, so the client's read fails (ECONNRESET)
        poll_until(lambda: client.errors == 1, client)
        assert client.last_error == "ConnectionResetError: [Errno 104] Connection reset by peer"
        assert not client.is_connected
        client.close()
