"""The compiled request frame and reader against pymodbus's own framing of the same write."""

import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest

from hilrig.drivers.joint_targets.frame import (
    BAD_CRC,
    NOT_FINITE,
    UNKNOWN_MODE,
    RequestFrame,
    RequestReader,
    _pymodbus_frame,
)
from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
from hilrig.errors import ProtocolError

angles = st.floats(-7.0, 7.0, allow_nan=False)  # any finite joint angle a clamp can command


@settings(max_examples=300, deadline=None)
@given(
    q=st.tuples(*[angles] * 6),
    sequence=st.integers(0, 0xFFFF),
    mode=st.sampled_from(list(Mode)),
    device_id=st.integers(1, 247),
)
def test_frames_are_byte_for_byte_pymodbus_frames(
    q: tuple[float, ...], sequence: int, mode: Mode, device_id: int
) -> None:
    register_map = RegisterMap(device_id=device_id)
    request = RequestFrame(register_map)
    request.fill(np.array(q), sequence, mode)
    expected = _pymodbus_frame(register_map, JointTargets(q, sequence, mode))
    assert request.frame.tobytes() == expected


def test_another_register_layout_is_framed_the_same_way() -> None:
    register_map = RegisterMap(targets=(2, 12), sequence=(0, 1), mode=(1, 1), device_id=7)
    request = RequestFrame(register_map)
    q = (0.1, -0.2, 1.5, -3.0, 2.25, 6.0)
    for sequence, mode in ((1, Mode.TRACK), (0xFFFF, Mode.STOP), (2, Mode.HOLD)):
        request.fill(np.array(q), sequence, mode)
        expected = _pymodbus_frame(register_map, JointTargets(q, sequence, mode))
        assert request.frame.tobytes() == expected


layouts = st.sampled_from(
    [RegisterMap(), RegisterMap(targets=(2, 12), sequence=(0, 1), mode=(1, 1), device_id=7)]
)


@settings(max_examples=400, deadline=None)
@given(
    register_map=layouts,
    registers=st.lists(st.integers(0, 0xFFFF), min_size=14, max_size=14),
    known_mode=st.booleans(),
    corrupt=st.integers(-1, 36),
)
def test_the_reader_decodes_what_register_map_decodes_and_refuses_what_it_refuses(
    register_map: RegisterMap, registers: list[int], known_mode: bool, corrupt: int
) -> None:
    """Any 14 registers (targets of any bit pattern: NaN, inf, subnormal), framed by pymodbus,
    one byte flipped or none: the reader's result and targets against ``RegisterMap.decode``
    and the CRC pymodbus checks."""
    if known_mode:
        registers[register_map.mode[0] - register_map.start] %= len(Mode)
    frame = bytearray(
        FramerRTU(DecodePDU(is_server=False)).buildFrame(
            WriteMultipleRegistersRequest(
                address=register_map.start, registers=registers, dev_id=register_map.device_id
            )
        )
    )
    if corrupt >= 0:
        frame[corrupt] ^= 0x5A
    reader = RequestReader(register_map)
    result = reader.read(frame + b"\x01\x10")  # the next request's first bytes may follow
    if not FramerRTU.check_CRC(bytes(frame[:-2]), int.from_bytes(frame[-2:], "big")):
        assert result == BAD_CRC
        return
    try:
        decoded = register_map.decode(list(struct.unpack(">14H", frame[7:-2])))
    except ProtocolError as refused:
        assert result == (NOT_FINITE if "not finite" in str(refused) else UNKNOWN_MODE)
        return
    assert result >= 0
    assert (result >> 16, RequestReader.mode(result)) == (decoded.sequence, decoded.mode)
    assert tuple(reader.q_rad.tolist()) == decoded.q_rad
