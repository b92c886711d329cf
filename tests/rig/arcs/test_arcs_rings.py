"""The ARCS link's rings read by compiled code: the same rows, in the same order, as the
rings' own Python consumer (the oracle), whatever the interleaving of writes and reads."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.rig.arcs.shared import COMMAND_DTYPE, newest_row, take_rows
from hilrig.rig.rings import Ring, RingSpec


def _pair(capacity: int) -> tuple[Ring, Ring]:
    """Two rings that get the same writes: one read in Python, one by the compiled reader."""
    a = Ring.create(RingSpec.unique("ta", COMMAND_DTYPE, capacity))
    b = Ring.create(RingSpec.unique("tb", COMMAND_DTYPE, capacity))
    return a, b


def _row(i: int) -> tuple[int, int, int, list[float]]:
    return (i, 10 * i, i % 3, [i + 0.5 * j for j in range(6)])


@settings(max_examples=60, deadline=None)
@given(
    capacity=st.integers(1, 9),
    steps=st.lists(st.tuples(st.integers(0, 12), st.integers(1, 8)), min_size=1, max_size=12),
)
def test_take_rows_reads_what_the_python_consumer_reads(
    capacity: int, steps: list[tuple[int, int]]
) -> None:
    python_side, compiled_side = _pair(capacity)
    out = np.zeros(8, dtype=COMMAND_DTYPE)
    written = 0
    try:
        for writes, room in steps:
            for _ in range(writes):
                python_side.push(*_row(written))
                compiled_side.push(*_row(written))
                written += 1
            expected = python_side.read_available()[:room]
            # the Python side read everything: hand back what the compiled side may leave
            got = out[: take_rows(compiled_side.rows, compiled_side.header, out[:room])]
            assert got.tobytes() == expected.tobytes()
            rest = compiled_side.backlog
            while rest:  # drain the rest so both sides stand at the same index
                rest -= take_rows(compiled_side.rows, compiled_side.header, out)
        assert python_side.dropped == compiled_side.dropped
    finally:
        for ring in (python_side, compiled_side):
            ring.close()
            ring.unlink()


def test_newest_row_takes_the_last_and_releases_all() -> None:
    ring = Ring.create(RingSpec.unique("tn", COMMAND_DTYPE, 4))
    out = np.zeros(1, dtype=COMMAND_DTYPE)
    try:
        assert newest_row(ring.rows, ring.header, out) == 0
        assert out[0]["t_ns"] == 0  # untouched
        for i in range(1, 4):
            ring.push(*_row(i))
        assert newest_row(ring.rows, ring.header, out) == 3
        assert out[0]["t_ns"] == 3 and out[0]["q"].tolist() == _row(3)[3]
        assert ring.backlog == 0
        for i in range(4, 9):  # one more than fits: the ninth is refused, counted
            ring.push(*_row(i))
        assert ring.dropped == 1
        assert newest_row(ring.rows, ring.header, out) == 4
        assert out[0]["t_ns"] == 7
    finally:
        ring.close()
        ring.unlink()
