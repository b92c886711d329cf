"""The joint-target request frame, filled in place by a compiled kernel for the real-time loop.

pymodbus builds the Modbus RTU request (function 16, write multiple registers) once, as a
template: device id, function code, start address, register count and byte count. Each tick
only the register bytes (six float32 targets, the watchdog counter, the mode) and the CRC-16
change; :func:`fill_request` writes them into the template in place, using pymodbus's own
CRC table, so a request costs a few microseconds instead of pymodbus's per-request Python
(about 50 us here) and allocates nothing. ``tests/drivers/test_joint_targets_frame.py`` checks
the frames byte for byte against pymodbus's ``FramerRTU.buildFrame`` for any targets.
:class:`RequestReader` is the other end, for the emulated robot: one compiled call checks a
whole-map write's CRC and decodes it, as ``RegisterMap.decode`` does (tested against it).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest

from hilrig.compiled import njit
from hilrig.drivers.joint_targets.wire import JOINTS, JointTargets, Mode, RegisterMap
from hilrig.timing import bound_kernel

_DATA_AT = 7  # device id, function, address (2), count (2), byte count (1)
_CRC_TABLE = np.array(FramerRTU.crc16_table, dtype=np.uint16)


class RequestFrame:
    """One reusable request of ``register_map``: ``fill(q_rad, sequence, mode)`` (or write
    :attr:`q_rad` in place and ``fill_from_q(sequence, mode)``), then send :attr:`frame` (a
    uint8 array, a buffer ``os.write`` takes)."""

    def __init__(self, register_map: RegisterMap) -> None:
        self._map = register_map
        template = _pymodbus_frame(register_map, JointTargets((0.0,) * JOINTS, 0, Mode.HOLD))
        self.frame = np.frombuffer(bytearray(template), dtype=np.uint8)
        start = register_map.start
        self._targets_at = _DATA_AT + 2 * (register_map.targets[0] - start)
        self._sequence_at = _DATA_AT + 2 * (register_map.sequence[0] - start)
        self._mode_at = _DATA_AT + 2 * (register_map.mode[0] - start)
        self.q_rad = np.zeros(JOINTS)
        self.incoming = np.zeros(JOINTS)
        self.stage: Callable[[], bool] = bound_kernel(
            copy_if_finite, self.incoming, self.q_rad, last=()
        )
        """``stage()``: copies :attr:`incoming` to :attr:`q_rad` if every target is finite; whether
        it did (no per-call dispatch)."""
        self._f32 = np.zeros(JOINTS, dtype=np.float32)
        self.fill_from_q: Callable[[int, int], None] = bound_kernel(
            fill_request,
            self.frame,
            self.q_rad,
            self._targets_at,
            self._sequence_at,
            self._mode_at,
            _CRC_TABLE,
            self._f32,
            last=(0, 0),
        )
        """``fill_from_q(sequence, mode)``: the frame of :attr:`q_rad` (finite: the caller
        checks), the counter and the mode (an int), with its CRC (no per-call dispatch)."""

    def fill(self, q_rad: NDArray[np.float64], sequence: int, mode: Mode) -> None:
        """Write targets (6,), rad (finite: the caller checks), counter and mode, and the CRC."""
        self.q_rad[:] = q_rad
        self.fill_from_q(sequence, int(mode))


#: ``read_request``'s results for a write it does not decode (one it does: sequence << 16 | mode)
BAD_CRC, NOT_FINITE, UNKNOWN_MODE = -1, -2, -3
_MODES = tuple(Mode)  # by code: Mode's values are 0, 1, 2


class RequestReader:
    """The receiving side of :class:`RequestFrame`: a write of the whole of ``register_map``
    (its first bytes already matched) decoded in place by one compiled call.

    ``read(rx)`` takes the bytearray the request arrived in (at least :attr:`size` bytes),
    checks its CRC-16, writes the targets (rad) into :attr:`q_rad` and returns
    ``sequence << 16 | mode``, or BAD_CRC, NOT_FINITE or UNKNOWN_MODE: the writes
    ``RegisterMap.decode`` refuses with ProtocolError. An emulated robot reads one a millisecond;
    this is a microsecond of the slot where struct, the decode and its record took tens.
    """

    def __init__(self, register_map: RegisterMap) -> None:
        start = register_map.start
        self.size = _DATA_AT + 2 * register_map.count + 2
        self.q_rad = np.zeros(JOINTS)
        self.read: Callable[[bytearray], int] = bound_kernel(
            read_request,
            self.q_rad,
            np.zeros(JOINTS, dtype=np.uint32),
            _DATA_AT + 2 * (register_map.targets[0] - start),
            _DATA_AT + 2 * (register_map.sequence[0] - start),
            _DATA_AT + 2 * (register_map.mode[0] - start),
            len(_MODES),
            self.size,
            _CRC_TABLE,
            last=(bytearray(self.size),),
        )

    @staticmethod
    def mode(result: int) -> Mode:
        """The mode of a decoded write (``read``'s result >= 0)."""
        return _MODES[result & 0xFFFF]


def rtu_frame_size(decoder: DecodePDU, buffer: bytes | bytearray) -> int:
    """Bytes of the RTU frame at the start of ``buffer`` by pymodbus's own sizing of its
    function; 0 while incomplete, ``len(buffer)`` for a function pymodbus does not know (nothing
    after it can be framed). pymodbus's ``FramerRTU.handleFrame`` takes a whole buffer as one
    frame, so pipelined frames are cut with this first."""
    if len(buffer) < FramerRTU.MIN_SIZE:
        return 0
    pdu_class = decoder.lookupPduClass(bytes(buffer[:2]))
    if pdu_class is None:
        return len(buffer)
    size = int(pdu_class.calculateRtuFrameSize(bytes(buffer)))
    return size if 0 < size <= len(buffer) else 0


def _pymodbus_frame(register_map: RegisterMap, targets: JointTargets) -> bytes:
    """The request as pymodbus frames it (the template, and the tests' oracle)."""
    request = WriteMultipleRegistersRequest(
        address=register_map.start,
        registers=register_map.encode(targets),
        dev_id=register_map.device_id,
    )
    frame: bytes = FramerRTU(DecodePDU(is_server=False)).buildFrame(request)
    return frame


@njit(cache=True)
def copy_if_finite(source: NDArray[np.float64], target: NDArray[np.float64]) -> bool:
    """Copy ``source`` into ``target`` if every value is finite; whether it did."""
    for j in range(source.shape[0]):
        if not np.isfinite(source[j]):
            return False
    target[:] = source
    return True


@njit(cache=True)
def fill_request(
    frame: NDArray[np.uint8],
    q_rad: NDArray[np.float64],
    targets_at: int,
    sequence_at: int,
    mode_at: int,
    crc_table: NDArray[np.uint16],
    f32: NDArray[np.float32],
    sequence: int,
    mode: int,
) -> None:
    """Registers big-endian (float32 targets as two words, high first), then the CRC-16/MODBUS
    of everything before it, low byte first, as pymodbus writes it."""
    for j in range(q_rad.shape[0]):
        f32[j] = q_rad[j]
    words = f32.view(np.uint32)
    for j in range(q_rad.shape[0]):
        w = words[j]
        at = targets_at + 4 * j
        frame[at] = (w >> 24) & 0xFF
        frame[at + 1] = (w >> 16) & 0xFF
        frame[at + 2] = (w >> 8) & 0xFF
        frame[at + 3] = w & 0xFF
    frame[sequence_at] = (sequence >> 8) & 0xFF
    frame[sequence_at + 1] = sequence & 0xFF
    frame[mode_at] = (mode >> 8) & 0xFF
    frame[mode_at + 1] = mode & 0xFF
    end = frame.shape[0] - 2
    crc = crc16(frame, end, crc_table)
    frame[end] = crc & 0xFF
    frame[end + 1] = (crc >> 8) & 0xFF


@njit(cache=True)
def crc16(
    data: NDArray[np.uint8] | bytes | bytearray, end: int, crc_table: NDArray[np.uint16]
) -> int:
    """The CRC-16/MODBUS of ``data[:end]`` by pymodbus's table (sent low byte first)."""
    crc = 0xFFFF
    for i in range(end):
        crc = ((crc >> 8) & 0xFF) ^ crc_table[(crc ^ data[i]) & 0xFF]
    return crc


@njit(cache=True)
def read_request(
    q_rad: NDArray[np.float64],
    words: NDArray[np.uint32],
    targets_at: int,
    sequence_at: int,
    mode_at: int,
    modes: int,
    size: int,
    crc_table: NDArray[np.uint16],
    frame: bytearray,
) -> int:
    """The inverse of ``fill_request`` for the ``size``-byte request at the start of ``frame``:
    ``q_rad`` from its float32 targets and ``sequence << 16 | mode``, or BAD_CRC, NOT_FINITE
    (a target that is not finite) or UNKNOWN_MODE (not below ``modes``)."""
    end = size - 2
    if crc16(frame, end, crc_table) != _word(frame, end, 1, 0):
        return BAD_CRC
    for j in range(q_rad.shape[0]):
        at = targets_at + 4 * j
        words[j] = (_word(frame, at, 0, 1) << 16) | _word(frame, at + 2, 0, 1)
    floats = words.view(np.float32)
    for j in range(q_rad.shape[0]):
        q_rad[j] = floats[j]
        if not math.isfinite(q_rad[j]):
            return NOT_FINITE
    mode = _word(frame, mode_at, 0, 1)
    if mode >= modes:
        return UNKNOWN_MODE
    return (_word(frame, sequence_at, 0, 1) << 16) | mode


@njit(cache=True, inline="always")
def _word(frame: bytearray, at: int, high: int, low: int) -> int:
    """The 16-bit word of bytes ``at + high`` (its high byte) and ``at + low``, as an int64 (the
    bytes are uint8: numba would widen their mix with int64 to float64)."""
    return int((np.int64(frame[at + high]) << 8) | np.int64(frame[at + low]))
