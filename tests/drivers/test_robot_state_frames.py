"""The compiled joint-state decoder against the reference decoder, on any stream.

Oracle: ``RobotStateDecoder`` (the protocol's readable definition, itself tested against zlib and
struct in test_robot_state_codec.py). Both are fed the same bytes in the same pieces; the frames
and every counter must agree after each piece.
"""

import math
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from state_rows import as_state

from hilrig.drivers.robot_state.frames import RECV_BYTES, StateFrames
from hilrig.drivers.robot_state.wire import (
    FRAME_BYTES,
    MAGIC,
    STATE_DTYPE,
    RobotState,
    RobotStateDecoder,
    RobotStatus,
    encode,
)

ANY_FLOAT = st.one_of(
    st.floats(-15.0, 15.0),  # around the limits: 4 pi, 20 and 1000
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([4 * math.pi, math.nextafter(4 * math.pi, 99), 20.0, -1000.0, 1000.5]),
)


@st.composite
def frames(draw: st.DrawFn) -> bytes:
    """A frame of any values, status and sequence; sometimes with a byte flipped or a bad length."""
    values = draw(st.lists(ANY_FLOAT, min_size=18, max_size=18))
    state = RobotState(
        draw(st.integers(0, 2**32 - 1) | st.integers(0, 40)),
        draw(st.integers(-(2**63), 2**63 - 1)),
        tuple(values[:6]),
        tuple(values[6:12]),
        tuple(values[12:]),
        RobotStatus(draw(st.integers(0, 63))),
    )
    frame = bytearray(encode(state))
    damage = draw(st.sampled_from(["none", "none", "flip", "length"]))
    if damage == "flip":
        frame[draw(st.integers(0, FRAME_BYTES - 1))] ^= draw(st.integers(1, 255))
    elif damage == "length":
        struct.pack_into("<H", frame, 4, draw(st.integers(0, 0xFFFF).filter(lambda n: n != 164)))
    return bytes(frame)


def state(sequence: int) -> RobotState:
    q = (0.1 * (sequence % 7),) * 6
    return RobotState(sequence, 10**18 + sequence, q, (0.5,) * 6, (-2.0,) * 6, RobotStatus(3))


@settings(max_examples=400, deadline=None)
@given(
    chunks=st.lists(
        st.one_of(frames(), st.binary(max_size=200), st.just(MAGIC), st.just(MAGIC[:3])),
        max_size=25,
    ),
    splits=st.lists(st.integers(1, 400), max_size=20),
)
def test_the_compiled_decoder_decodes_and_counts_as_the_reference(
    chunks: list[bytes], splits: list[int]
) -> None:
    data = b"".join(chunks)
    reference, compiled = RobotStateDecoder(), StateFrames()
    pieces, at = [], 0
    for size in [*splits, len(data)]:
        pieces.append(data[at : at + size])
        at += size
    for t_ns, piece in enumerate(pieces, start=1):
        expected = reference.feed(piece)
        n = compiled.feed_bytes(piece, t_ns)
        rows = compiled.rows[:n]
        assert [as_state(row) for row in rows] == expected
        assert rows["t_ns"].tolist() == [t_ns] * n
        assert compiled.stats == reference.stats
        if expected:
            assert as_state(compiled.newest[0]) == expected[-1]


def test_rows_hold_every_frame_of_the_largest_feed() -> None:
    count = RECV_BYTES // FRAME_BYTES  # 385 whole frames, and a part of the next
    data = b"".join(encode(state(n)) for n in range(count + 1))
    decoder = StateFrames()
    assert decoder.feed_bytes(data[:RECV_BYTES], 7) == count
    assert [as_state(row) for row in decoder.rows[:count]] == [state(n) for n in range(count)]
    assert decoder.feed_bytes(data[RECV_BYTES:], 8) == 1  # the held part completed
    assert as_state(decoder.rows[0]) == state(count) and decoder.rows[0]["t_ns"] == 8
    assert decoder.stats.frames == count + 1 and decoder.stats.bytes_dropped == 0
    assert decoder.rows.dtype == STATE_DTYPE


def test_reset_forgets_held_bytes_and_the_last_sequence_but_keeps_the_counters() -> None:
    decoder = StateFrames()
    assert decoder.feed_bytes(encode(state(1)) + encode(state(2))[:100], 1) == 1
    decoder.reset()
    assert decoder.feed_bytes(encode(state(9)), 2) == 1  # not a gap: a new connection
    assert decoder.stats.frames == 2 and decoder.stats.sequence_gaps == 0
    assert decoder.stats.bytes_dropped == 0  # the held part was forgotten, not dropped
    assert np.array_equal(decoder.newest["seq"], [9])
