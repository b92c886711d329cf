"""The joint-target request frame, filled in place by a compiled kernel for the real-time loop.

pymodbus builds the Modbus RTU request (function 16, write multiple registers) once, as a
template: device id, function code, start address, register count and byte count. Each tick
only the register bytes (six float32 targets, the watchdog counter, the mode) and the CRC-16
change; :func:`fill_request` writes them into the template in place, using pymodbus's own
CRC table, so a request costs a few microseconds instead of pymodbus's per-request Python
(about 50 us here) and allocates nothing. ``tests/drivers/test_joint_targets_frame.py`` checks
the frames byte for byte against pymodbus's ``FramerRTU.buildFrame`` for any targets.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import NDArray
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest

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


def crc_ok(frame: bytes | bytearray, size: int) -> bool:
    """Whether the ``size``-byte RTU frame at the start of ``frame`` ends in its CRC-16/MODBUS
    (low byte first); compiled, a fraction of a microsecond against pymodbus's ~10 us."""
    crc = int(crc16(frame, size - 2, _CRC_TABLE))
    return crc == frame[size - 2] | frame[size - 1] << 8


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
