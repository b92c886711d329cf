"""The joint-state stream decoded by one compiled call into rows of arrays, for the real-time loop.

:class:`StateFrames` decodes exactly as :class:`~hilrig.drivers.robot_state.wire.RobotStateDecoder`
(magic, length, CRC-32, finite and plausible values, resynchronising one byte after a bad
frame's magic; the same counters) but writes each frame into a row of :data:`STATE_DTYPE`
stamped with the receive time, in a buffer made once: no bytes object, tuple or list per frame.
The reference decoder stays the protocol's readable definition and the tests' oracle
(``tests/drivers/test_robot_state_frames.py`` checks both on any stream, corrupt or not).

    frames = StateFrames()
    count = sock.recv_into(frames.free)       # the bytes go straight into its buffer
    n = frames.feed(count, now_ns)            # frames.rows[:n] are the frames completed now
    n = frames.receive(sock.fileno(), now_ns)  # or both in one compiled call (read(2))
"""

from __future__ import annotations

from dataclasses import fields

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
from hilrig.drivers.robot_state.crc import crc32
from hilrig.drivers.robot_state.wire import (
    FRAME_BYTES,
    JOINTS,
    LENGTH,
    MAGIC,
    MAX_ABS_Q_RAD,
    MAX_ABS_QD_RAD_S,
    MAX_ABS_TORQUE_NM,
    STATE_DTYPE,
    DecoderStats,
)

RECV_BYTES = 65536  # what one feed takes at most: 385 frames, far more than arrive in a tick
# the counters array: DecoderStats's fields in order, then the decoder's own state
_COUNTERS = tuple(f.name for f in fields(DecoderStats))
LAST_SEQUENCE = len(_COUNTERS)  # -1: no frame since the last reset; the held bytes' count next
(
    _FRAMES,
    _CRC_ERRORS,
    _LENGTH_ERRORS,
    _REJECTED,
    _RESYNCS,
    _DROPPED,
    _GAPS,
    _MISSED,
) = range(len(_COUNTERS))
_MAGIC = np.frombuffer(MAGIC, dtype=np.uint8).copy()
_CRC_AT = FRAME_BYTES - 4
_Q_AT = 18  # then qd and torque, 48 bytes each; status at 162 (docs/protocols.md)
_LIMITS = np.array([MAX_ABS_Q_RAD, MAX_ABS_QD_RAD_S, MAX_ABS_TORQUE_NM])


class StateFrames(CompiledDecoder):
    """A joint-state stream's decoder into :attr:`rows` of STATE_DTYPE, enough for any
    :data:`RECV_BYTES` fed at once."""

    def __init__(self) -> None:
        super().__init__(
            decode,
            receive,
            RECEIVE_LAYOUT,
            (_MAGIC, _LIMITS, np.zeros(1, dtype=np.uint64)),
            dtype=STATE_DTYPE,
            counters=LAST_SEQUENCE + 1,
            read_bytes=RECV_BYTES,
            keep_bytes=FRAME_BYTES,
            frame_bytes=FRAME_BYTES,
        )
        self.counters[LAST_SEQUENCE] = -1

    @property
    def stats(self) -> DecoderStats:
        """The counters since the decoder was made."""
        values = self.counters.tolist()
        return DecoderStats(**dict(zip(_COUNTERS, values, strict=False)))

    def reset(self) -> None:
        """Forget held bytes and the last sequence (after a reconnect); keep the counters."""
        self.forget_held()
        self.counters[LAST_SEQUENCE] = -1


@njit(cache=True)
def decode(
    buffer: NDArray[np.uint8],
    rows: NDArray[np.void],
    newest: NDArray[np.void],
    counters: NDArray[np.int64],
    magic: NDArray[np.uint8],
    limits: NDArray[np.float64],
    bits: NDArray[np.uint64],
    count: int,
    t_ns: int,
) -> int:
    """RobotStateDecoder.feed over ``buffer``'s held bytes and the ``count`` after them: frames
    into ``rows`` (returns how many), the newest also into ``newest``, the unused tail moved to
    the buffer's start."""
    end = counters[counters.shape[0] - 1] + count  # after the bytes held
    start = 0
    n = 0
    while True:
        at = find(buffer, magic, start, end)
        if at < 0:  # keep a tail that may be the start of a magic split across reads
            keep = end - (magic.shape[0] - 1)
            if keep > start:
                counters[_DROPPED] += keep - start
                start = keep
            break
        counters[_DROPPED] += at - start
        start = at
        if end - start < FRAME_BYTES:
            break
        if _parse(buffer, start, rows, n, counters, limits, bits):
            rows[n].t_ns = t_ns
            n += 1
            start += FRAME_BYTES
        else:
            counters[_RESYNCS] += 1
            counters[_DROPPED] += 1
            start += 1
    return finish(buffer, rows, newest, counters, start, end, n)


# receive's table: buffer, rows, newest, counters, magic, limits, bits, io
RECEIVE_LAYOUT: Layout = (
    (np.uint8, 1),
    (STATE_DTYPE, 1),
    (STATE_DTYPE, 1),
    (np.int64, 1),
    (np.uint8, 1),
    (np.float64, 1),
    (np.uint64, 1),
    (np.int64, 1),
)


@njit(cache=True)
def receive(table: NDArray[np.int64], fd: int, t_ns: int) -> int:
    """read(2) from ``fd`` into the buffer after the held bytes, then :func:`decode` them (the
    arrays of RECEIVE_LAYOUT by address)."""
    count = read_after_held(table, fd, RECV_BYTES)
    if count <= 0:
        return 0
    buffer, counters = view1(table, BUFFER, np.uint8), view1(table, COUNTERS, np.int64)
    rows, newest = view1(table, ROWS, STATE_DTYPE), view1(table, NEWEST, STATE_DTYPE)
    magic, limits = view1(table, 4, np.uint8), view1(table, 5, np.float64)
    return decode(
        buffer, rows, newest, counters, magic, limits, view1(table, 6, np.uint64), count, t_ns
    )


@njit(cache=True, inline="always")
def _bits64(buffer: NDArray[np.uint8], at: int, bits: NDArray[np.uint64]) -> None:
    """The 8 little-endian bytes at ``at`` into ``bits[0]``."""
    value = np.uint64(0)
    for k in range(8):
        value |= np.uint64(buffer[at + k]) << np.uint64(8 * k)
    bits[0] = value


@njit(cache=True)
def _parse(
    buffer: NDArray[np.uint8],
    at: int,
    rows: NDArray[np.void],
    n: int,
    counters: NDArray[np.int64],
    limits: NDArray[np.float64],
    bits: NDArray[np.uint64],
) -> bool:
    """The frame at ``at`` into ``rows[n]`` (but its t_ns) if length, CRC and values pass,
    counted as RobotStateDecoder._parse counts; whether it did."""
    row = rows[n]
    if unsigned_le(buffer, at + 4, 2) != LENGTH:
        counters[_LENGTH_ERRORS] += 1
        return False
    if crc32(buffer[at:], _CRC_AT) != unsigned_le(buffer, at + _CRC_AT, 4):
        counters[_CRC_ERRORS] += 1
        return False
    floats = bits.view(np.float64)
    for j in range(3 * JOINTS):
        _bits64(buffer, at + _Q_AT + 8 * j, bits)
        value = floats[0]
        if not abs(value) <= limits[j // JOINTS]:  # NaN too
            counters[_REJECTED] += 1
            return False
        if j < JOINTS:
            row.q[j] = value
        elif j < 2 * JOINTS:
            row.qd[j - JOINTS] = value
        else:
            row.tau[j - 2 * JOINTS] = value
    sequence = unsigned_le(buffer, at + 6, 4)
    _bits64(buffer, at + 10, bits)
    row.device_t_ns = bits.view(np.int64)[0]
    row.seq = sequence
    row.status = unsigned_le(buffer, at + _Q_AT + 8 * 3 * JOINTS, 4)
    last = counters[LAST_SEQUENCE]
    if last >= 0:
        step = (sequence - last) & 0xFFFFFFFF
        if step != 1:
            counters[_GAPS] += 1
            if 1 < step < 0x80000000:
                counters[_MISSED] += step - 1
    counters[LAST_SEQUENCE] = sequence
    counters[_FRAMES] += 1
    return True
