"""Kunwei six-axis F/T sensor wire protocol (KWR75D, KWR200X): frames, samples and the framer.

One frame, 28 bytes, no checksum (docs/protocols.md)::

    offset size  field
    0      2     header 48 AA
    2      24    Fx Fy Fz Mx My Mz, 6 x float32 little-endian, kgf and kgf*m
    26     2     tail 0D 0A

Commands to the sensor: start streaming ``48 AA 0D 0A``, stop ``43 AA 0D 0A``.

:class:`KunweiFramer` turns a byte stream into :class:`FtSample` records in N and N*m. It is
pure (no I/O; the caller passes the receive time) and never raises on any input. While locked it
takes the frame at the expected boundary when header and tail are in place, so header bytes
inside the floats cannot mislead it. After a lost boundary it hunts: a candidate is accepted
only when its tail is in place, its values are finite and in range and the next frame's header
follows it. Frames whose values are non-finite or out of range are dropped whole and counted.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

HEADER = b"\x48\xaa"
TAIL = b"\x0d\x0a"
START_COMMAND = b"\x48\xaa\x0d\x0a"
STOP_COMMAND = b"\x43\xaa\x0d\x0a"
FRAME = struct.Struct("<2s6f2s")
FRAME_BYTES = FRAME.size  # 28
KGF_N = 9.80665  # N per kgf (standard gravity); also N*m per kgf*m

_PAYLOAD = struct.Struct("<6f")
_H0, _H1 = HEADER
_T0, _T1 = TAIL

Wrench = tuple[float, float, float, float, float, float]

# One sample as a row (FtFrames, the loop's rings): an FtSample's fields
SAMPLE_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),  # host receive time (monotonic ns)
        ("seq", np.int64),  # the driver's frame counter
        ("wrench", np.float64, (6,)),  # Fx Fy Fz (N) Mx My Mz (N*m), sensor frame, as measured
    ]
)


class FtSample(NamedTuple):
    """One accepted frame: host receive time, frame number and the measured wrench.

    A named tuple, immutable like a frozen dataclass but made in a fifth of the time (one a
    millisecond on the loop's thread).

    ``t_ns`` is the host monotonic time (time.monotonic_ns) of the read that completed the
    frame; ``seq`` counts accepted frames from 0 (the protocol carries no device counter);
    ``wrench_in_sensor`` is (Fx, Fy, Fz) in N and (Mx, My, Mz) in N*m in the sensor frame, as
    measured (no tare, no compensation).
    """

    t_ns: int
    seq: int
    wrench_in_sensor: Wrench

    @property
    def force_in_sensor_n(self) -> tuple[float, float, float]:
        fx, fy, fz = self.wrench_in_sensor[:3]
        return fx, fy, fz

    @property
    def torque_in_sensor_nm(self) -> tuple[float, float, float]:
        mx, my, mz = self.wrench_in_sensor[3:]
        return mx, my, mz


@dataclass(frozen=True, slots=True)
class FramerConfig:
    """Scaling and plausibility limits of one sensor.

    ``kgf_scale`` converts device units to SI (N per kgf, N*m per kgf*m; 1.0 for a sensor set to
    output N). A frame with any |force| above ``max_abs_force_n`` or |torque| above
    ``max_abs_torque_nm`` is implausible and rejected: set them a margin above the sensor's
    rated range (the defaults are above any KWR75/KWR200 rating).
    """

    kgf_scale: float = KGF_N
    max_abs_force_n: float = 5000.0
    max_abs_torque_nm: float = 500.0


@dataclass(frozen=True, slots=True)
class FramerStats:
    """Counters since the framer was made.

    Every byte fed is accounted for:
    ``bytes_in == FRAME_BYTES * (frames + frames_rejected) + bytes_dropped + bytes_buffered``.
    ``resyncs`` counts the times the frame boundary was lost and hunted for again.
    """

    bytes_in: int
    frames: int
    frames_rejected: int
    resyncs: int
    bytes_dropped: int
    bytes_buffered: int
    locked: bool


def encode_frame(wrench_in_sensor: tuple[float, ...], *, kgf_scale: float = KGF_N) -> bytes:
    """The 28 frame bytes carrying ``wrench_in_sensor`` (N, N*m), converted to device units.

    Raises OverflowError if a value does not fit a float32 after scaling.
    """
    return FRAME.pack(HEADER, *(v / kgf_scale for v in wrench_in_sensor), TAIL)


class KunweiFramer:
    """Byte stream in, :class:`FtSample` records out; resynchronises after any corruption."""

    def __init__(self, config: FramerConfig | None = None) -> None:
        self.config = FramerConfig() if config is None else config
        self._buffer = bytearray()
        self._locked = False
        self._bytes_in = 0
        self._frames = 0
        self._rejected = 0
        self._resyncs = 0
        self._dropped = 0

    @property
    def stats(self) -> FramerStats:
        return FramerStats(
            bytes_in=self._bytes_in,
            frames=self._frames,
            frames_rejected=self._rejected,
            resyncs=self._resyncs,
            bytes_dropped=self._dropped,
            bytes_buffered=len(self._buffer),
            locked=self._locked,
        )

    def reset(self) -> None:
        """Forget buffered bytes and the frame boundary (after a reconnect); keep the counters."""
        self._buffer.clear()
        self._locked = False

    def feed(self, data: bytes, t_ns: int | None = None) -> list[FtSample]:
        """The frames completed by ``data``, stamped ``t_ns`` (default: time.monotonic_ns())."""
        if t_ns is None:
            t_ns = time.monotonic_ns()
        buf = self._buffer
        buf += data
        self._bytes_in += len(data)
        end = len(buf)
        samples: list[FtSample] = []
        pos = 0
        while True:
            if self._locked:
                if end - pos < FRAME_BYTES:
                    break
                if (
                    buf[pos] == _H0
                    and buf[pos + 1] == _H1
                    and buf[pos + 26] == _T0
                    and buf[pos + 27] == _T1
                ):
                    sample = self._decode(buf, pos, t_ns)
                    if sample is None:
                        self._rejected += 1
                    else:
                        samples.append(sample)
                    pos += FRAME_BYTES
                    continue
                self._locked = False
                self._resyncs += 1
                self._dropped += 1  # pos is not a frame start
                pos += 1
            at = buf.find(HEADER, pos)
            if at < 0:
                keep = 1 if end > pos and buf[end - 1] == _H0 else 0  # half a header
                self._dropped += end - keep - pos
                pos = end - keep
                break
            self._dropped += at - pos
            pos = at
            if end - pos < FRAME_BYTES + 2:
                break  # wait for the tail and the next header
            if (
                buf[pos + 26] == _T0
                and buf[pos + 27] == _T1
                and buf[pos + 28] == _H0
                and buf[pos + 29] == _H1
            ):
                sample = self._decode(buf, pos, t_ns)
                if sample is not None:
                    samples.append(sample)
                    self._locked = True
                    pos += FRAME_BYTES
                    continue
            self._dropped += 1
            pos += 1
        del buf[:pos]
        return samples

    def _decode(self, buf: bytearray, pos: int, t_ns: int) -> FtSample | None:
        """The sample at ``pos`` if every value is finite and in range, else None."""
        scale = self.config.kgf_scale
        fx, fy, fz, mx, my, mz = _PAYLOAD.unpack_from(buf, pos + 2)
        fx, fy, fz, mx, my, mz = (
            fx * scale,
            fy * scale,
            fz * scale,
            mx * scale,
            my * scale,
            mz * scale,
        )
        f_max = self.config.max_abs_force_n
        m_max = self.config.max_abs_torque_nm
        # NaN fails every comparison, so this also refuses non-finite values
        if not (
            abs(fx) <= f_max
            and abs(fy) <= f_max
            and abs(fz) <= f_max
            and abs(mx) <= m_max
            and abs(my) <= m_max
            and abs(mz) <= m_max
        ):
            return None
        seq = self._frames
        self._frames = seq + 1
        return FtSample(t_ns, seq, (fx, fy, fz, mx, my, mz))
