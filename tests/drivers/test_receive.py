"""The compiled decoders' ``receive``: read(2) and decoding in one call, on real descriptors.

Oracle: the same decoder fed the same bytes through ``feed_bytes`` (itself checked against the
reference decoders in test_robot_state_frames.py and test_ft_frames.py); the system's own
answers (EAGAIN on an empty non-blocking descriptor, 0 at a stream's end or from a hung-up pty,
EBADF) come back as the read's result.
"""

import errno
import os
import socket
import tty

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.compiled_decoder import CompiledDecoder
from hilrig.drivers.ft.frames import FtFrames
from hilrig.drivers.ft.wire import FRAME, HEADER, TAIL, FramerConfig
from hilrig.drivers.robot_state.frames import StateFrames
from hilrig.drivers.robot_state.wire import RobotState, RobotStatus, encode
from hilrig.drivers.sys_read import read_error


def joint_frame(sequence: int) -> bytes:
    q = (0.01 * (sequence % 50),) * 6
    return encode(
        RobotState(sequence, 10**12 + sequence, q, (0.2,) * 6, (1.5,) * 6, RobotStatus(1))
    )


def ft_frame(k: int) -> bytes:
    return FRAME.pack(HEADER, 0.1 * k, -0.2, 1.0, 0.01, 0.0, -0.03, TAIL)


def state_of(decoder: CompiledDecoder, n: int) -> tuple[bytes, list[int]]:
    return decoder.rows[:n].tobytes(), decoder.counters.tolist()


@settings(max_examples=60, deadline=None)
@given(
    kind=st.sampled_from(["joint", "ft"]),
    pieces=st.lists(st.binary(max_size=64) | st.integers(0, 40), min_size=1, max_size=12),
)
def test_receive_decodes_what_feed_decodes_from_the_bytes_read(
    kind: str, pieces: list[bytes | int]
) -> None:
    make = StateFrames if kind == "joint" else (lambda: FtFrames(FramerConfig()))
    frame = joint_frame if kind == "joint" else ft_frame
    received, fed = make(), make()
    a, b = socket.socketpair()
    with a, b:
        a.setblocking(False)
        total = 0
        for t_ns, piece in enumerate(pieces, start=1):
            data = frame(piece) if isinstance(piece, int) else piece
            if data:
                b.sendall(data)
            n = received.receive(a.fileno(), t_ns)
            if data:
                assert received.last_read == len(data)
                assert state_of(received, n) == state_of(fed, fed.feed_bytes(data, t_ns))
                assert received.newest.tobytes() == fed.newest.tobytes()
            else:  # nothing waiting on a non-blocking socket
                assert (n, received.last_read) == (0, -errno.EAGAIN)
                assert read_error(received.last_read) is None
            total += len(data)
        assert received.io[0] == total
        b.close()
        assert received.receive(a.fileno(), 99) == 0 and received.last_read == 0  # the end


def test_a_bad_descriptor_is_the_system_s_error() -> None:
    decoder = StateFrames()
    assert decoder.receive(-1, 1) == 0
    assert decoder.last_read == -errno.EBADF
    error = read_error(decoder.last_read)
    assert isinstance(error, OSError) and str(error) == "[Errno 9] Bad file descriptor"


def test_a_pty_reads_its_bytes_then_nothing_once_its_other_side_closed() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(slave, False)
    framer = FtFrames(FramerConfig())
    try:
        assert framer.receive(slave, 1) == 0 and framer.last_read == -errno.EAGAIN
        os.write(master, ft_frame(1) + ft_frame(2) + HEADER)
        n = framer.receive(slave, 2)  # a read takes what the tty's worker still holds
        assert n == 2 and framer.last_read == 2 * FRAME.size + 2
        os.close(master)  # hung up: reads end (0), as an empty tty's do; writes fail (EIO)
        assert framer.receive(slave, 3) == 0 and framer.last_read == 0
        with pytest.raises(OSError, match=r"\[Errno 5\]"):
            os.write(slave, b"H")
    finally:
        os.close(slave)


@pytest.mark.parametrize("result", [-errno.EAGAIN, -errno.EINTR, 0, 5])
def test_reads_that_are_not_errors(result: int) -> None:
    assert read_error(result) is None
