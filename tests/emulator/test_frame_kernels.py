"""The emulated rig's compiled frames against struct packing of the same values (the wire
modules' own encoders) and zlib's CRC-32, byte for byte."""

import struct
import zlib

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.ft.wire import FRAME, HEADER, TAIL
from hilrig.drivers.robot_state.crc import crc32
from hilrig.drivers.robot_state.wire import (
    FRAME_BYTES,
    LENGTH,
    MAGIC,
    RobotState,
    RobotStatus,
    encode,
)
from hilrig.emulator.frame_kernels import ft_frame_into, state_frame_into

FINITE = st.floats(-1e6, 1e6, allow_nan=False)
SIX = st.lists(FINITE, min_size=6, max_size=6)


@settings(deadline=None)  # the first call loads the compiled kernel
@given(st.binary(max_size=300))
def test_crc32_is_zlibs(data: bytes) -> None:
    assert crc32(np.frombuffer(data, dtype=np.uint8), len(data)) == zlib.crc32(data)


@settings(max_examples=200, deadline=None)
@given(
    wrench=SIX,
    bias=SIX,
    noise=SIX,
    rotation=st.lists(st.floats(-1, 1), min_size=9, max_size=9),
    gravity=st.lists(st.floats(-20, 20), min_size=3, max_size=3),
    tool=st.lists(st.floats(-5, 5), min_size=18, max_size=18),
    oriented=st.booleans(),
    scale=st.floats(0.01, 10),
)
def test_ft_frame_is_struct_packing_of_the_device_values(
    wrench: list[float],
    bias: list[float],
    noise: list[float],
    rotation: list[float],
    gravity: list[float],
    tool: list[float],
    oriented: bool,
    scale: float,
) -> None:
    r = [rotation[0:3], rotation[3:6], rotation[6:9]]
    gx, gy, gz = gravity
    s = [r[0][c] * gx + r[1][c] * gy + r[2][c] * gz for c in range(3)]
    rows = [tool[3 * a : 3 * a + 3] for a in range(6)]
    gravity_wrench = [m[0] * s[0] + m[1] * s[1] + m[2] * s[2] if oriented else 0.0 for m in rows]
    expected = [
        (e + b + n + g) * scale
        for e, b, n, g in zip(wrench, bias, noise, gravity_wrench, strict=True)
    ]
    frame = np.frombuffer(bytearray(FRAME.pack(HEADER, *(0.0,) * 6, TAIL)), np.uint8)
    values = np.zeros(6)
    noise_block = np.array([[9.0] * 6, noise, [9.0] * 6])
    ft_frame_into(
        frame,
        values,
        np.zeros(6, np.float32),
        np.array(wrench),
        np.array(bias),
        noise_block,
        np.array(r),
        np.array(gravity),
        np.array(rows),
        1,
        oriented,
        scale,
    )
    assert values.tolist() == expected
    assert frame.tobytes() == FRAME.pack(HEADER, *expected, TAIL)


@settings(max_examples=200, deadline=None)
@given(
    q=SIX,
    qd=SIX,
    torque=SIX,
    noise=SIX,
    sequence=st.integers(0, 2**40),
    device_t_ns=st.integers(-(2**63), 2**63 - 1),
    status=st.integers(0, 63),
)
def test_state_frame_is_the_wire_encoding(
    q: list[float],
    qd: list[float],
    torque: list[float],
    noise: list[float],
    sequence: int,
    device_t_ns: int,
    status: int,
) -> None:
    frame = np.zeros(FRAME_BYTES, np.uint8)
    frame[:6] = np.frombuffer(struct.pack("<4sH", MAGIC, LENGTH), np.uint8)
    state_frame_into(
        frame,
        np.zeros(18),
        np.zeros(3, np.uint32),
        np.zeros(1, np.int64),
        np.array(q),
        np.array(qd),
        np.array(torque),
        np.array([noise, [7.0] * 6]),
        0,
        sequence,
        device_t_ns,
        status,
    )
    measured = tuple(t + n for t, n in zip(torque, noise, strict=True))
    state = RobotState(sequence, device_t_ns, tuple(q), tuple(qd), measured, RobotStatus(status))
    assert frame.tobytes() == encode(state)
