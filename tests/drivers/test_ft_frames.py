"""The compiled F/T framer against the reference framer, on any stream.

Oracle: ``KunweiFramer`` (the protocol's readable definition, itself pinned down in
test_ft_framer.py). Both are fed the same bytes in the same pieces; the samples and every
counter must agree after each piece.
"""

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_ft_framer import UNIT, any_wrenches, cut, frames, garbage

from hilrig.drivers.ft.frames import READ_BYTES, FtFrames
from hilrig.drivers.ft.wire import (
    FRAME_BYTES,
    SAMPLE_DTYPE,
    FramerConfig,
    FtSample,
    KunweiFramer,
    encode_frame,
)

TIGHT = FramerConfig(max_abs_force_n=20.0, max_abs_torque_nm=2.0)  # kgf scale, low limits


def as_samples(rows: Any) -> list[FtSample]:
    return [
        FtSample(int(row["t_ns"]), int(row["seq"]), tuple(row["wrench"].tolist())) for row in rows
    ]


@pytest.mark.parametrize("config", [UNIT, FramerConfig(), TIGHT], ids=["unit", "kgf", "tight"])
@settings(max_examples=300, deadline=None)
@given(data=st.data(), pieces=st.lists(st.one_of(garbage, any_wrenches.map(frames)), max_size=8))
def test_the_compiled_framer_frames_and_counts_as_the_reference(
    config: FramerConfig, data: st.DataObject, pieces: list[bytes]
) -> None:
    reference, compiled = KunweiFramer(config), FtFrames(config)
    for t_ns, piece in enumerate(cut(data, b"".join(pieces)), start=1):
        expected = reference.feed(piece, t_ns)
        n = compiled.feed_bytes(piece, t_ns)
        assert as_samples(compiled.rows[:n]) == expected
        assert compiled.stats == reference.stats
        if expected:
            assert as_samples(compiled.newest) == expected[-1:]


def test_rows_hold_every_sample_of_the_largest_feed() -> None:
    count = READ_BYTES // FRAME_BYTES
    one = encode_frame((1.0, 2.0, 3.0, 0.1, 0.2, 0.3))
    data = one * (count + 2)
    framer = FtFrames()
    assert framer.feed_bytes(data[:READ_BYTES], 5) == count  # the first locks, the rest follow
    assert framer.stats.bytes_buffered == READ_BYTES - count * FRAME_BYTES  # part of the next
    assert framer.feed_bytes(data[READ_BYTES:], 6) == 2
    assert framer.rows["seq"][:2].tolist() == [count, count + 1]
    assert framer.rows.dtype == SAMPLE_DTYPE


def test_reset_forgets_the_boundary_and_held_bytes_but_keeps_the_counters() -> None:
    one = encode_frame((1.0, 2.0, 3.0, 0.1, 0.2, 0.3))
    framer = FtFrames()
    assert framer.feed_bytes(one * 2 + one[:10], 1) == 2
    framer.reset()
    stats = framer.stats
    assert (stats.locked, stats.bytes_buffered, stats.frames) == (False, 0, 2)
    assert framer.feed_bytes(one + one[:2], 2) == 1  # hunting again: a header must follow
