"""The Kunwei F/T stream framed by one compiled call into rows of arrays, for the real-time loop.

:class:`FtFrames` frames exactly as :class:`~hilrig.drivers.ft.wire.KunweiFramer` (locked on the
frame boundary, hunting after a lost one for a frame whose tail and the next header are in
place; values scaled to N and N*m; frames non-finite or out of range dropped whole; the same
counters) but writes each sample into a row of :data:`~hilrig.drivers.ft.wire.SAMPLE_DTYPE`
stamped with the receive time, in a buffer made once: no bytes object, tuple or list per frame.
The reference framer stays the protocol's readable definition and the tests' oracle
(``tests/drivers/test_ft_frames.py`` checks both on any stream, corrupt or not).

    frames = FtFrames(FramerConfig())
    count = os.readv(fd, [frames.free])       # the bytes go straight into its buffer
    n = frames.feed(count, now_ns)            # frames.rows[:n] are the samples completed now
    n = frames.receive(fd, now_ns)            # or both in one compiled call (read(2))
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import Layout, view1
from hilrig.compiled import njit
from hilrig.drivers.compiled_decoder import (
    BUFFER,
    COUNTERS,
    NEWEST,
    ROWS,
    CompiledDecoder,
    find,
    finish,
    read_after_held,
    unsigned_le,
)
from hilrig.drivers.ft.wire import (
    FRAME_BYTES,
    HEADER,
    SAMPLE_DTYPE,
    TAIL,
    FramerConfig,
    FramerStats,
)

READ_BYTES = 65536  # what one feed takes at most: 2340 frames
# the counters array, then the held bytes' count
BYTES_IN, FRAMES, REJECTED, RESYNCS, DROPPED, LOCKED = range(6)
_H0, _H1 = HEADER
_HEADER = np.frombuffer(HEADER, dtype=np.uint8).copy()
_T0, _T1 = TAIL


class FtFrames(CompiledDecoder):
    """A Kunwei stream's framer into :attr:`rows` of SAMPLE_DTYPE (N and N*m, sensor frame)."""

    def __init__(self, config: FramerConfig | None = None) -> None:
        self.config = FramerConfig() if config is None else config
        limits = (self.config.kgf_scale, self.config.max_abs_force_n, self.config.max_abs_torque_nm)
        super().__init__(
            frame,
            receive,
            RECEIVE_LAYOUT,
            (np.array(limits), np.zeros(1, dtype=np.uint32)),
            dtype=SAMPLE_DTYPE,
            counters=LOCKED + 1,
            read_bytes=READ_BYTES,
            keep_bytes=FRAME_BYTES + 2,  # a frame and the next header, while hunting
            frame_bytes=FRAME_BYTES,
        )

    @property
    def stats(self) -> FramerStats:
        """The counters since the framer was made."""
        bytes_in, frames, rejected, resyncs, dropped, locked, held = self.counters.tolist()
        return FramerStats(bytes_in, frames, rejected, resyncs, dropped, held, bool(locked))

    def reset(self) -> None:
        """Forget held bytes and the frame boundary (after a reconnect); keep the counters."""
        self.forget_held()
        self.counters[LOCKED] = 0


@njit(cache=True)
def frame(
    buffer: NDArray[np.uint8],
    rows: NDArray[np.void],
    newest: NDArray[np.void],
    counters: NDArray[np.int64],
    limits: NDArray[np.float64],
    bits: NDArray[np.uint32],
    count: int,
    t_ns: int,
) -> int:
    """KunweiFramer.feed over ``buffer``'s held bytes and the ``count`` after them: samples into
    ``rows`` (returns how many), the newest also into ``newest``, the rest moved to the start."""
    counters[BYTES_IN] += count
    end = counters[counters.shape[0] - 1] + count  # after the bytes held
    locked = counters[LOCKED] != 0
    pos = 0
    n = 0
    while True:
        if locked:
            if end - pos < FRAME_BYTES:
                break
            if _framed(buffer, pos, False):
                if _sample(buffer, pos, rows, n, counters, limits, bits, t_ns):
                    n += 1
                else:
                    counters[REJECTED] += 1
                pos += FRAME_BYTES
                continue
            locked = False
            counters[RESYNCS] += 1
            counters[DROPPED] += 1  # pos is not a frame start
            pos += 1
        at = find(buffer, _HEADER, pos, end)
        if at < 0:
            keep = 1 if end > pos and buffer[end - 1] == _H0 else 0  # half a header
            counters[DROPPED] += end - keep - pos
            pos = end - keep
            break
        counters[DROPPED] += at - pos
        pos = at
        if end - pos < FRAME_BYTES + 2:
            break  # wait for the tail and the next header
        if _framed(buffer, pos, True) and _sample(
            buffer, pos, rows, n, counters, limits, bits, t_ns
        ):
            n += 1
            locked = True
            pos += FRAME_BYTES
            continue
        counters[DROPPED] += 1
        pos += 1
    counters[LOCKED] = 1 if locked else 0
    return finish(buffer, rows, newest, counters, pos, end, n)


# receive's table: buffer, rows, newest, counters, limits, bits, io
RECEIVE_LAYOUT: Layout = (
    (np.uint8, 1),
    (SAMPLE_DTYPE, 1),
    (SAMPLE_DTYPE, 1),
    (np.int64, 1),
    (np.float64, 1),
    (np.uint32, 1),
    (np.int64, 1),
)


@njit(cache=True)
def receive(table: NDArray[np.int64], fd: int, t_ns: int) -> int:
    """read(2) from ``fd`` into the buffer after the held bytes, then :func:`frame` them (the
    arrays of RECEIVE_LAYOUT by address)."""
    count = read_after_held(table, fd, READ_BYTES)
    if count <= 0:
        return 0
    buffer, counters = view1(table, BUFFER, np.uint8), view1(table, COUNTERS, np.int64)
    rows, newest = view1(table, ROWS, SAMPLE_DTYPE), view1(table, NEWEST, SAMPLE_DTYPE)
    limits, bits = view1(table, 4, np.float64), view1(table, 5, np.uint32)
    return frame(buffer, rows, newest, counters, limits, bits, count, t_ns)


@njit(cache=True, inline="always")
def _framed(buffer: NDArray[np.uint8], pos: int, next_header: bool) -> bool:
    """Header and tail in place at ``pos`` (and, hunting, the next frame's header after it)."""
    at = pos + FRAME_BYTES if next_header else pos
    return bool(
        buffer[pos + 26] == _T0
        and buffer[pos + 27] == _T1
        and buffer[at] == _H0
        and buffer[at + 1] == _H1
    )


@njit(cache=True)
def _sample(
    buffer: NDArray[np.uint8],
    pos: int,
    rows: NDArray[np.void],
    n: int,
    counters: NDArray[np.int64],
    limits: NDArray[np.float64],
    bits: NDArray[np.uint32],
    t_ns: int,
) -> bool:
    """The frame at ``pos`` into ``rows[n]``, numbered, if every value is finite and in range
    (KunweiFramer._decode); whether it was."""
    row = rows[n]
    floats = bits.view(np.float32)
    for j in range(6):
        bits[0] = unsigned_le(buffer, pos + 2 + 4 * j, 4)
        scaled = np.float64(floats[0]) * limits[0]
        if not abs(scaled) <= limits[1 if j < 3 else 2]:  # NaN too
            return False
        row.wrench[j] = scaled
    row.t_ns = t_ns
    row.seq = counters[FRAMES]
    counters[FRAMES] += 1
    return True
