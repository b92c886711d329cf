"""hilrig's robot joint-state wire format (docs/protocols.md) and its stream decoder.

One frame, little-endian, 170 bytes::

    offset size  field
    0      4     magic b"HRS1"
    4      2     length: bytes from sequence through CRC (164)
    6      4     sequence, uint32, +1 per frame (wraps)
    10     8     device time, int64 ns (the controller's clock)
    18     48    q, 6 x float64, rad
    66     48    qd, 6 x float64, rad/s
    114    48    joint torque, 6 x float64, N*m
    162    4     status bits, uint32 (RobotStatus)
    166    4     CRC-32 (zlib) of bytes 0..165

The decoder resynchronises on the magic after any corruption, checks length, CRC and finite
values, and counts every frame it drops and every sequence gap. Pure: no I/O, no clock.
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass
from enum import IntFlag
from typing import NamedTuple

import numpy as np

MAGIC = b"HRS1"
JOINTS = 6
_HEAD = struct.Struct("<4sH")
_CRC = struct.Struct("<I")
_PAYLOAD = struct.Struct("<Iq" + "d" * (3 * JOINTS) + "I")
FRAME_BYTES = _HEAD.size + _PAYLOAD.size + _CRC.size
LENGTH = _PAYLOAD.size + _CRC.size
MAX_ABS_Q_RAD = 4 * math.pi  # beyond any joint's range: a value like this is corruption
MAX_ABS_QD_RAD_S = 20.0
MAX_ABS_TORQUE_NM = 1000.0

# One decoded frame as a row (StateFrames, the loop's rings): the host receive time (monotonic ns)
# and the frame's fields, SI units
STATE_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),
        ("device_t_ns", np.int64),  # the controller's clock
        ("seq", np.int64),  # the controller's frame sequence
        ("q", np.float64, (JOINTS,)),  # rad
        ("qd", np.float64, (JOINTS,)),  # rad/s
        ("tau", np.float64, (JOINTS,)),  # joint torque, N*m
        ("status", np.int64),  # RobotStatus bits
    ]
)


class RobotStatus(IntFlag):
    """Status bits of a frame."""

    ENABLED = 1
    TRACKING = 2  # following the Modbus joint targets
    HOLDING = 4  # holding position (watchdog expired or told to hold)
    PROTECTIVE_STOP = 8
    EMERGENCY_STOP = 16
    FAULT = 32


class RobotState(NamedTuple):
    """One joint-state frame: device time (ns), sequence, q (rad), qd (rad/s), torque (N*m).

    A named tuple: immutable, and made in a fifth of a frozen dataclass's time (1 kHz)."""

    sequence: int
    device_t_ns: int
    q_rad: tuple[float, ...]
    qd_rad_s: tuple[float, ...]
    torque_nm: tuple[float, ...]
    status: RobotStatus


_STATUSES = tuple(RobotStatus(code) for code in range(64))  # every combination of the bits


def _within(values: tuple[float, ...], limit: float) -> bool:
    """Every value finite and within +-``limit``, in C-level loops (a frame a millisecond): NaN
    makes the sum NaN (``s == s`` false); an infinity is above any limit."""
    total = sum(values)
    return total == total and max(map(abs, values)) <= limit


def encode(state: RobotState) -> bytes:
    """The frame bytes of ``state`` (sequence taken modulo 2**32)."""
    payload = _PAYLOAD.pack(
        state.sequence & 0xFFFFFFFF,
        state.device_t_ns,
        *state.q_rad,
        *state.qd_rad_s,
        *state.torque_nm,
        int(state.status),
    )
    head = _HEAD.pack(MAGIC, LENGTH) + payload
    return head + _CRC.pack(zlib.crc32(head))


@dataclass
class DecoderStats:
    """Counters of a decoder since it was made (all monotonic)."""

    frames: int = 0
    crc_errors: int = 0
    length_errors: int = 0
    rejected_values: int = 0
    resyncs: int = 0
    bytes_dropped: int = 0
    sequence_gaps: int = 0
    frames_missed: int = 0  # frames implied missing by sequence gaps


class RobotStateDecoder:
    """Turns a byte stream into RobotState frames, resyncing on corruption.

    ``feed(data)`` returns the complete valid frames found so far; partial frames wait for
    more bytes. A frame with a bad length, CRC or a non-finite/out-of-range value is dropped
    and counted, and decoding resumes at the next magic after its first byte.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._last_sequence: int | None = None
        self.stats = DecoderStats()

    def feed(self, data: bytes) -> list[RobotState]:
        self._buffer += data
        buffer = self._buffer
        frames: list[RobotState] = []
        start = 0
        while True:
            at = buffer.find(MAGIC, start)
            if at < 0:
                # keep a tail that may be the start of a magic split across reads
                keep = len(buffer) - (len(MAGIC) - 1)
                if keep > start:
                    self._drop(keep - start)
                    start = keep
                break
            if at > start:
                self._drop(at - start)
            start = at
            if len(buffer) - start < FRAME_BYTES:
                break
            state = self._parse(bytes(buffer[start : start + FRAME_BYTES]))
            if state is None:
                self.stats.resyncs += 1
                self._drop(1)
                start += 1
                continue
            frames.append(state)
            start += FRAME_BYTES
        del buffer[:start]
        return frames

    def reset(self) -> None:
        """Forget buffered bytes and the last sequence (after a reconnect); keep the counters."""
        self._buffer.clear()
        self._last_sequence = None

    def _drop(self, count: int) -> None:
        self.stats.bytes_dropped += count

    def _parse(self, frame: bytes) -> RobotState | None:
        _, length = _HEAD.unpack_from(frame, 0)
        if length != LENGTH:
            self.stats.length_errors += 1
            return None
        (crc,) = _CRC.unpack_from(frame, FRAME_BYTES - _CRC.size)
        if zlib.crc32(frame[: FRAME_BYTES - _CRC.size]) != crc:
            self.stats.crc_errors += 1
            return None
        values = _PAYLOAD.unpack_from(frame, _HEAD.size)
        sequence, device_t_ns = values[0], values[1]
        q = values[2 : 2 + JOINTS]
        qd = values[2 + JOINTS : 2 + 2 * JOINTS]
        torque = values[2 + 2 * JOINTS : 2 + 3 * JOINTS]
        if not (
            _within(q, MAX_ABS_Q_RAD)
            and _within(qd, MAX_ABS_QD_RAD_S)
            and _within(torque, MAX_ABS_TORQUE_NM)
        ):
            self.stats.rejected_values += 1
            return None
        self._count_sequence(sequence)
        self.stats.frames += 1
        code = values[-1]
        status = _STATUSES[code] if code < len(_STATUSES) else RobotStatus(code)
        return RobotState(sequence, device_t_ns, q, qd, torque, status)

    def _count_sequence(self, sequence: int) -> None:
        if self._last_sequence is not None:
            step = (sequence - self._last_sequence) & 0xFFFFFFFF
            if step != 1:
                self.stats.sequence_gaps += 1
                if 1 < step < 0x80000000:
                    self.stats.frames_missed += step - 1
        self._last_sequence = sequence
