"""``damping_ratio_rows``, the compiled zeta of replay's table rows, against ``damping_ratio`` (the
one formula, in NumPy): the same bits for any floats, infinities, zeros and negatives included,
and NaN where NumPy gives NaN, on contiguous rows and on the strided rows of a result table.

A NaN's payload is not compared: when two NaNs meet, IEEE 754 leaves which one's payload the
result carries to the hardware and to the order of the operands, which a compiler may swap in a
product (a fresh clone's run found 0 / (sqrt(NaN * NaN') * 2) carrying the other NaN's payload).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hilrig.control import damping_ratio, damping_ratio_rows

ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, width=64)
SPECIAL = st.sampled_from([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 5e-324, 1e308])


def bits(values: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(values).view(np.int64)


def assert_same_values(got: np.ndarray, expected: np.ndarray) -> None:
    """NaN where ``expected`` is NaN, and every other value with its bits (signed zeros too)."""
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(got), nan)
    np.testing.assert_array_equal(bits(got)[~nan], bits(expected)[~nan])


@settings(deadline=None)  # the first example compiles the kernel for its array types
@given(
    st.integers(1, 4).flatmap(
        lambda axes: st.tuples(
            arrays(np.float64, (axes, 7), elements=ANY_FLOAT | SPECIAL),
            arrays(np.float64, (axes, 7), elements=ANY_FLOAT | SPECIAL),
            arrays(np.float64, (axes,), elements=ANY_FLOAT | SPECIAL),
        )
    )
)
def test_every_zeta_has_the_bits_of_the_numpy_formula(
    arrays_: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    damping, stiffness, mass = arrays_
    out = np.full_like(damping, 123.0)
    with np.errstate(all="ignore"):
        expected = damping_ratio(damping, stiffness, mass[:, None])
    damping_ratio_rows(damping, stiffness, mass, out)
    assert_same_values(out, expected)


def test_the_strided_rows_of_a_table_are_written_in_place_and_nothing_else() -> None:
    """As replay calls it: (axes, quantities, ticks) blocks, one quantity's rows of a run."""
    rng = np.random.default_rng(3)
    blocks = rng.uniform(0.1, 50.0, size=(9, 6, 1000))
    before = blocks.copy()
    rows = slice(200, 700)
    mass = rng.uniform(0.5, 5.0, size=9)
    damping_ratio_rows(blocks[:, 3, rows], blocks[:, 4, rows], mass, blocks[:, 5, rows])
    expected = damping_ratio(before[:, 3, rows], before[:, 4, rows], mass[:, None])
    np.testing.assert_array_equal(bits(blocks[:, 5, rows]), bits(expected))
    blocks[:, 5, rows] = before[:, 5, rows]
    np.testing.assert_array_equal(blocks, before)
