"""What the drivers' compiled stream decoders share: bytes received straight into their buffer,
decoded by one bound kernel call into rows of a fixed dtype.

A decoder (the joint-state stream's :class:`~hilrig.drivers.robot_state.frames.StateFrames`,
the F/T sensor's :class:`~hilrig.drivers.ft.frames.FtFrames`) holds:

- a byte buffer: the bytes a previous feed left (a frame's start) followed by the room
  :attr:`~CompiledDecoder.free` the link reads into, up to ``read_bytes`` at a time;
- ``rows``: the frames of the last feed (its first ``n``), each stamped with the receive time;
- ``newest``: one row, the newest frame ever decoded, kept current in place;
- int64 counters, the last of which is how many bytes the buffer holds from before;
- ``io``: the bytes its receiver has read and the last read's result (:mod:`.sys_read`).

Its kernel is ``kernel(buffer, rows, newest, counters, *constants, count, t_ns) -> n``: it
decodes the held bytes and the ``count`` new ones after them, writes the frames into
``rows[:n]`` and ends with :func:`finish` (the newest into ``newest``, the bytes it keeps moved
to the buffer's start). :func:`find` and :func:`unsigned_le` are the kernels' other shared
parts. Its receiver ``receiver(table, fd, t_ns) -> n`` takes the same arrays and then ``io``
by address (an :class:`~hilrig.array_table.ArrayTable` of the layout the decoder gives, so a
call unboxes one array, not seven), reads what waits on a link's descriptor into the buffer
(:func:`~.sys_read.read_into`) and calls the kernel on it: the drivers' loop reads and decodes a
link with one call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import ArrayTable, Layout, view1
from hilrig.compiled import njit
from hilrig.drivers.sys_read import IO_WORDS, LAST_READ, read_into
from hilrig.timing import bound_kernel


class CompiledDecoder:
    """The buffer, rows, counters and bound kernel of a compiled stream decoder."""

    def __init__(
        self,
        kernel: Any,
        receiver: Any,
        receiver_layout: Layout,
        constants: tuple[Any, ...],
        *,
        dtype: np.dtype[Any],
        counters: int,
        read_bytes: int,
        keep_bytes: int,
        frame_bytes: int,
    ) -> None:
        """``counters`` the decoder's own (the held count comes after them); at most
        ``keep_bytes`` are kept between feeds; a frame is at least ``frame_bytes``."""
        self.read_bytes = read_bytes
        self.rows = np.zeros((keep_bytes + read_bytes) // frame_bytes + 1, dtype=dtype)
        """The frames of the last :meth:`feed` (its first ``n``), oldest first."""
        self.newest = np.zeros(1, dtype=dtype)
        """The newest frame ever decoded (its one row; zeros before the first)."""
        self._buffer = np.zeros(keep_bytes + read_bytes, dtype=np.uint8)
        self._memory = self._buffer.data
        self.counters: NDArray[np.int64] = np.zeros(counters + 1, dtype=np.int64)
        self._held = counters
        self.io: NDArray[np.int64] = np.zeros(IO_WORDS, dtype=np.int64)
        arrays = (self._buffer, self.rows, self.newest, self.counters, *constants)
        self._feed: Callable[[int, int], int] = bound_kernel(kernel, *arrays, last=(0, 0))
        self.receive: Callable[[int, int], int] = ArrayTable((*arrays, self.io)).bind(
            receiver, receiver_layout, last=(0, 0)
        )
        """``receive(fd, t_ns) -> n``: read(2) what waits on ``fd`` (non-blocking) into
        :attr:`free` and decode it, in one compiled call; the frames are ``rows[:n]`` stamped
        ``t_ns``, and :attr:`last_read` says what the read got."""

    @property
    def free(self) -> memoryview:
        """Where the next received bytes go (up to ``read_bytes``): after those held."""
        held = int(self.counters[self._held])
        return self._memory[held : held + self.read_bytes]

    def feed(self, count: int, t_ns: int) -> int:
        """Decode the ``count`` bytes just written into :attr:`free`; the frames completed are
        ``rows[:n]`` stamped ``t_ns`` (n returned). A partial frame waits for more bytes."""
        return self._feed(count, t_ns)

    @property
    def last_read(self) -> int:
        """What the last :attr:`receive` read: bytes (0 at a stream's end, or from an empty tty
        set for timeout 0), or ``-errno`` (:func:`~.sys_read.read_error`)."""
        return int(self.io[LAST_READ])

    def feed_bytes(self, data: bytes, t_ns: int) -> int:
        """:meth:`feed` of ``data`` (at most ``read_bytes``), copied in: for tests and tools."""
        self.free[: len(data)] = data
        return self.feed(len(data), t_ns)

    def forget_held(self) -> None:
        """Drop the bytes held from earlier feeds (after a reconnect), uncounted."""
        self.counters[self._held] = 0


# Rows of a receiver's table (an ArrayTable): the buffer, rows, newest, counters, then the
# decoder's constants; its io array last.
BUFFER, ROWS, NEWEST, COUNTERS = range(4)


@njit(cache=True, inline="always")
def read_after_held(table: NDArray[np.int64], fd: int, size: int) -> int:
    """read(2) of up to ``size`` bytes from ``fd`` into a receiver's buffer after the bytes it
    holds (:func:`~.sys_read.read_into`, its io array the table's last row)."""
    counters = view1(table, COUNTERS, np.int64)
    held = counters[counters.shape[0] - 1]
    io = view1(table, table.shape[0] - 1, np.int64)
    return read_into(fd, view1(table, BUFFER, np.uint8), held, size, io)


@njit(cache=True, inline="always")
def find(buffer: NDArray[np.uint8], marker: NDArray[np.uint8], start: int, end: int) -> int:
    """The first index >= ``start`` where ``marker`` lies whole before ``end``; -1 if none."""
    for at in range(start, end - marker.shape[0] + 1):
        k = 0
        while k < marker.shape[0] and buffer[at + k] == marker[k]:
            k += 1
        if k == marker.shape[0]:
            return at
    return -1


@njit(cache=True, inline="always")
def unsigned_le(buffer: NDArray[np.uint8], at: int, size: int) -> int:
    """The little-endian unsigned integer of ``size`` (<= 4) bytes at ``at``."""
    value = 0
    for k in range(size):
        value |= int(buffer[at + k]) << (8 * k)
    return value


@njit(cache=True, inline="always")
def finish(
    buffer: NDArray[np.uint8],
    rows: NDArray[np.void],
    newest: NDArray[np.void],
    counters: NDArray[np.int64],
    start: int,
    end: int,
    n: int,
) -> int:
    """A feed's end: ``buffer[start:end]`` (the bytes kept) moved to its start and counted as
    held (the counters' last), the newest of the ``n`` rows into ``newest``; returns ``n``."""
    for i in range(start, end):  # to the front, no copy made
        buffer[i - start] = buffer[i]
    counters[counters.shape[0] - 1] = end - start
    if n:
        newest[0] = rows[n - 1]
    return n
