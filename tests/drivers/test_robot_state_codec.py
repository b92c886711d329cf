"""The robot joint-state wire format: round trips, resync, and counting of every drop."""

import math
import struct
import zlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.robot_state.wire import (
    FRAME_BYTES,
    MAGIC,
    RobotState,
    RobotStateDecoder,
    RobotStatus,
    encode,
)


def state(sequence: int, q0: float = 0.1) -> RobotState:
    return RobotState(
        sequence=sequence,
        device_t_ns=1_000_000 * sequence,
        q_rad=(q0, -0.2, 0.3, -0.4, 0.5, -0.6),
        qd_rad_s=(0.01, 0.0, -0.02, 0.0, 0.0, 0.03),
        torque_nm=(1.5, -2.5, 0.0, 0.25, 0.0, -0.125),
        status=RobotStatus.ENABLED | RobotStatus.TRACKING,
    )


def test_frame_layout_is_the_documented_one() -> None:
    frame = encode(state(7))
    assert len(frame) == FRAME_BYTES == 170
    assert frame[:4] == b"HRS1"
    assert struct.unpack_from("<HIq", frame, 4) == (164, 7, 7_000_000)
    assert struct.unpack_from("<d", frame, 18)[0] == 0.1
    assert struct.unpack_from("<I", frame, 162)[0] == 3
    assert struct.unpack_from("<I", frame, 166)[0] == zlib.crc32(frame[:166])


def test_round_trip_of_a_stream() -> None:
    decoder = RobotStateDecoder()
    sent = [state(n) for n in range(50)]
    assert decoder.feed(b"".join(encode(s) for s in sent)) == sent
    assert decoder.stats.frames == 50
    assert decoder.stats.bytes_dropped == decoder.stats.sequence_gaps == 0


@pytest.mark.parametrize("cut", range(1, FRAME_BYTES))
def test_a_frame_split_anywhere_decodes_once(cut: int) -> None:
    decoder = RobotStateDecoder()
    data = encode(state(1)) + encode(state(2))
    assert decoder.feed(data[:cut]) == ([state(1)] if cut >= FRAME_BYTES else [])
    assert decoder.feed(data[cut:]) == [state(1), state(2)]
    assert decoder.stats.bytes_dropped == 0


def test_garbage_and_a_bad_crc_are_dropped_and_counted() -> None:
    decoder = RobotStateDecoder()
    corrupt = bytearray(encode(state(2)))
    corrupt[40] ^= 0xFF
    data = b"\x00garbage" + MAGIC + encode(state(1)) + bytes(corrupt) + encode(state(3))
    assert decoder.feed(data) == [state(1), state(3)]
    stats = decoder.stats
    assert stats.crc_errors == 1
    assert stats.sequence_gaps == 1 and stats.frames_missed == 1
    assert stats.bytes_dropped == 8 + 4 + FRAME_BYTES


def test_non_finite_values_are_rejected() -> None:
    decoder = RobotStateDecoder()
    bad = RobotState(1, 0, (math.nan,) + (0.0,) * 5, (0.0,) * 6, (0.0,) * 6, RobotStatus(0))
    assert decoder.feed(encode(bad) + encode(state(2))) == [state(2)]
    assert decoder.stats.rejected_values == 1


def test_sequence_wraps_without_a_gap() -> None:
    decoder = RobotStateDecoder()
    frames = decoder.feed(encode(state(0xFFFFFFFF)) + encode(state(0)))
    assert [f.sequence for f in frames] == [0xFFFFFFFF, 0]
    assert decoder.stats.sequence_gaps == 0


@settings(max_examples=300, deadline=None)
@given(
    chunks=st.lists(
        st.one_of(
            st.binary(max_size=300),
            st.integers(0, 1000).map(lambda n: encode(state(n))),
            st.just(MAGIC),
        ),
        max_size=30,
    ),
    splits=st.lists(st.integers(1, 400), max_size=20),
)
def test_fuzz_never_raises_and_recovers_on_the_next_clean_frame(
    chunks: list[bytes], splits: list[int]
) -> None:
    decoder = RobotStateDecoder()
    data = b"".join(chunks)
    out: list[RobotState] = []
    at = 0
    for size in splits:
        out += decoder.feed(data[at : at + size])
        at += size
    out += decoder.feed(data[at:])
    for frame in out:
        assert all(math.isfinite(v) for v in frame.q_rad + frame.qd_rad_s + frame.torque_nm)
    # after any garbage, clean frames decode from the first one on (garbage cannot hide them)
    clean = [state(5000), state(5001)]
    assert decoder.feed(b"".join(encode(s) for s in clean))[-2:] == clean
