"""The compiled request frame against pymodbus's own framing of the same write."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.joint_targets.frame import RequestFrame, _pymodbus_frame
from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap

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
