"""The emulated rig's two frames a slot, each made by one compiled call into buffers of its own.

``ft_frame_into`` computes the F/T sensor's device values (the external wrench plus bias, one
row of noise and the tool's gravity at the sensor's orientation, in kgf) and writes them as the
Kunwei frame's six float32; ``state_frame_into`` writes a whole joint-state frame (sequence, time,
q, qd, the joints' torque plus noise, status, CRC-32). Byte for byte what ``struct`` packing of
the same arithmetic gives (``drivers/ft/wire.FRAME``, ``drivers/robot_state/wire.encode``; the
tests hold them to it). In Python these took 150-200 us of a slot right after the rig's sleep
on a slow machine (cold caches: ten times their time in a tight loop).

Multi-byte fields are written through typed scratch arrays viewed as bytes, so the host must be
little-endian, as the wire is (checked at import).
"""

from __future__ import annotations

import sys

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.drivers.robot_state.crc import crc32

if sys.byteorder != "little":  # pragma: no cover - every platform hilrig runs on
    raise ImportError("hilrig.emulator.frame_kernels writes little-endian frames natively")

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@njit(cache=True)
def ft_frame_into(
    frame: U8,
    values: F64,
    floats: NDArray[np.float32],
    wrench: F64,
    bias: F64,
    noise: F64,
    rotation: F64,
    gravity: F64,
    tool_map: F64,
    row: int,
    oriented: bool,
    scale: float,
) -> None:
    """Device values (wrench + bias + noise[row] + tool gravity at ``rotation``, times ``scale``)
    into ``values`` (float64) and, as float32, into bytes 2..25 of ``frame``; ``oriented`` False:
    no tool gravity (the term is 0.0). ``tool_map`` (6, 3) maps gravity in the sensor frame,
    R^T g, to the tool's wrench."""
    gx, gy, gz = gravity[0], gravity[1], gravity[2]
    sx = rotation[0, 0] * gx + rotation[1, 0] * gy + rotation[2, 0] * gz
    sy = rotation[0, 1] * gx + rotation[1, 1] * gy + rotation[2, 1] * gz
    sz = rotation[0, 2] * gx + rotation[1, 2] * gy + rotation[2, 2] * gz
    for a in range(6):
        tool = tool_map[a, 0] * sx + tool_map[a, 1] * sy + tool_map[a, 2] * sz if oriented else 0.0
        value = (wrench[a] + bias[a] + noise[row, a] + tool) * scale
        values[a] = value
        floats[a] = value
    frame[2:26] = floats.view(np.uint8)


@njit(cache=True)
def state_frame_into(
    frame: U8,
    doubles: F64,
    words: NDArray[np.uint32],
    times: NDArray[np.int64],
    q_rad: F64,
    qd_rad_s: F64,
    torque_nm: F64,
    noise: F64,
    row: int,
    sequence: int,
    device_t_ns: int,
    status: int,
) -> None:
    """The joint-state frame of q, qd and torque + noise[row] into ``frame`` (170 bytes whose
    first six, magic and length, are set), its CRC-32 included."""
    for j in range(6):
        doubles[j] = q_rad[j]
        doubles[6 + j] = qd_rad_s[j]
        doubles[12 + j] = torque_nm[j] + noise[row, j]
    words[0] = sequence & 0xFFFFFFFF
    times[0] = device_t_ns
    words[1] = status
    frame[6:10] = words[0:1].view(np.uint8)
    frame[10:18] = times.view(np.uint8)
    frame[18:162] = doubles.view(np.uint8)
    frame[162:166] = words[1:2].view(np.uint8)
    words[2] = crc32(frame, 166)
    frame[166:170] = words[2:3].view(np.uint8)
