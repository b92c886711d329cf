"""The emulated devices' outbox on a real pty and a real socket pair: frames are dropped whole
while the reader does not read, and sending resumes as soon as it reads again (a sensor whose
reader stalled once used to stay silent for good: the backlog at its limit was never flushed)."""

from __future__ import annotations

import os
import socket
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.emulator.outbox import Outbox
from hilrig.emulator.pty_link import PtyLink

FRAME = b"\x48\xaa" + bytes(range(24)) + b"\x0d\x0a"


def drain(read: Callable[[], bytes]) -> bytes:
    got = b""
    while chunk := read():
        got += chunk
    return got


def pty_pair() -> tuple[
    Callable[[bytes | bytearray], int], Callable[[], bytes], Callable[[], None]
]:
    folder = Path(tempfile.mkdtemp())
    link = PtyLink(folder / "tty")
    reader = os.open(folder / "tty", os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)

    def read() -> bytes:
        try:
            return os.read(reader, 4096)
        except BlockingIOError:
            return b""

    def close() -> None:
        os.close(reader)
        link.close(folder / "tty")

    return link.write, read, close


def socket_pair() -> tuple[
    Callable[[bytes | bytearray], int], Callable[[], bytes], Callable[[], None]
]:
    a, b = socket.socketpair()
    a.setblocking(False)
    b.setblocking(False)

    def write(data: bytes | bytearray) -> int:
        try:
            return a.send(data)
        except BlockingIOError:
            return 0

    def read() -> bytes:
        try:
            return b.recv(65536)
        except BlockingIOError:
            return b""

    def close() -> None:
        a.close()
        b.close()

    return write, read, close


@pytest.mark.parametrize("link", [pty_pair, socket_pair])
def test_sending_resumes_once_the_reader_reads_again(link: Callable[..., tuple]) -> None:  # type: ignore[type-arg]
    write, read, close = link()
    try:
        out = Outbox(write, 4096)
        put = 0
        while out.frames_dropped == 0:  # nobody reads: the kernel's buffer, then the backlog fill
            out.put(FRAME)
            put += 1
        for _ in range(100):  # still nobody reads: every frame is dropped, whole
            out.put(FRAME)
            put += 1
        before, dropped = out.frames_sent, out.frames_dropped
        received = drain(read)
        for _ in range(10):  # the reader is back
            out.put(FRAME)
            put += 1
            received += drain(read)
        out.flush()
        received += drain(read)
        assert out.frames_dropped == dropped  # once the reader reads, no frame is dropped
        assert out.frames_sent >= before + 10  # the backlog went out, then every new frame
        assert out.frames_sent + out.frames_dropped == put and out.unsent == 0
        assert received == FRAME * out.frames_sent  # whole frames, in order, nothing cut
    finally:
        close()


@settings(max_examples=300, deadline=None)
@given(
    steps=st.lists(st.tuples(st.integers(1, 300), st.booleans(), st.integers(0, 400)), max_size=60),
    limit=st.integers(1, 600),
)
def test_every_byte_leaves_in_order_and_every_frame_is_counted_once(
    steps: list[tuple[int, bool, int]], limit: int
) -> None:
    """Against a writer that takes a given number of bytes each call (the kernel's free buffer
    space, here scripted): what leaves is exactly the queued stream, in order; a frame counts
    as sent when its last byte has left, dropped when it would pass the limit, never both."""
    room = [0]
    left: list[bytes] = []

    def write(data: bytes | bytearray) -> int:
        taken = min(room[0], len(data))
        room[0] -= taken
        left.append(bytes(data[:taken]))
        return taken

    out = Outbox(write, limit)
    stream, ends, dropped = b"", [], 0
    for size, frame, space in steps:
        room[0] = space
        data = bytes((len(stream) + k) % 251 for k in range(size))
        pending = len(stream) - len(b"".join(left))
        pending -= min(space, pending)  # put first writes what waits
        if frame and pending + size > limit:
            dropped += 1
        else:
            stream += data
            if frame:
                ends.append(len(stream))
        out.put(data, frame=frame)
    sent_bytes = b"".join(left)
    assert stream.startswith(sent_bytes)
    assert out.unsent == len(stream) - len(sent_bytes)
    assert out.frames_dropped == dropped
    assert out.frames_sent == sum(end <= len(sent_bytes) for end in ends)
