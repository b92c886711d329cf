"""Arrays by address (hilrig.array_table): a bound entry sees and changes the very arrays it was
given, as the same kernel called with them does; tables of arrays it cannot hold are refused."""

from __future__ import annotations

import gc
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numba import njit
from numpy.typing import NDArray

from hilrig.array_table import ArrayTable, Layout, view1, view2, view3
from hilrig.errors import ParameterError

RECORD = np.dtype([("t_ns", np.int64), ("wrench", np.float64, (6,))])
LAYOUT: Layout = ((np.float64, 1), (np.int64, 2), (np.uint8, 3), (RECORD, 1))


@njit(cache=False)
def kernel(
    a: NDArray[np.float64],
    b: NDArray[np.int64],
    c: NDArray[np.uint8],
    rows: NDArray[np.void],
    k: int,
) -> float:
    """Reads every element, writes a pattern into each array; a checksum of what it read."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i] * (i + 1)
        a[i] = a[i] * 2.0 + k
    for i in range(b.shape[0]):
        for j in range(b.shape[1]):
            total += b[i, j] * (i + 2 * j + 1)
            b[i, j] = i * 100 + j + k
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            for m in range(c.shape[2]):
                total += c[i, j, m] * (i + j + m + 1)
                c[i, j, m] = (i + j + m + k) % 256
    for i in range(rows.shape[0]):
        total += rows[i].t_ns + rows[i].wrench[5]
        rows[i].t_ns = i + k
        rows[i].wrench[2] = -1.5 * k
    return total


@njit(cache=False)
def entry(table: NDArray[np.int64], k: int) -> float:
    return kernel(
        view1(table, 0, np.float64),
        view2(table, 1, np.int64),
        view3(table, 2, np.uint8),
        view1(table, 3, RECORD),
        k,
    )


def _arrays(draw: Callable[..., Any]) -> tuple[NDArray[Any], ...]:
    side = st.integers(1, 5)
    a = draw(hnp.arrays(np.float64, draw(side), elements=st.floats(-1e6, 1e6)))
    b = draw(hnp.arrays(np.int64, (draw(side), draw(side)), elements=st.integers(-1000, 1000)))
    c = draw(hnp.arrays(np.uint8, (draw(side), draw(side), draw(side))))
    rows = np.zeros(draw(side), dtype=RECORD)
    rows["t_ns"] = draw(st.integers(0, 10**12))
    rows["wrench"][:, 5] = draw(st.floats(-100, 100))
    return a, b, c, rows


@settings(max_examples=60, deadline=None)
@given(data=st.data(), k=st.integers(-50, 50))
def test_a_bound_entry_reads_and_writes_the_arrays_as_the_kernel_given_them_does(
    data: st.DataObject, k: int
) -> None:
    given_arrays = _arrays(data.draw)
    copies = tuple(array.copy() for array in given_arrays)
    call = ArrayTable(given_arrays).bind(entry, LAYOUT, last=(0,))
    assert call(k) == kernel(*copies, k)
    for tabled, passed in zip(given_arrays, copies, strict=True):
        np.testing.assert_array_equal(tabled, passed)  # written in place, exactly alike


def test_the_table_keeps_its_arrays_alive_after_every_other_reference_is_gone() -> None:
    def bound() -> tuple[Callable[[int], float], weakref.ref[NDArray[np.float64]]]:
        a = np.arange(4.0)
        arrays = (a, np.ones((2, 2), np.int64), np.zeros((1, 1, 1), np.uint8), np.zeros(1, RECORD))
        return ArrayTable(arrays).bind(entry, LAYOUT, last=(0,)), weakref.ref(a)

    call, a = bound()
    gc.collect()
    assert a() is not None
    assert call(0) == 1 * 2 + 2 * 3 + 3 * 4 + (1 + 3 + 2 + 4)  # the arange and the ones, read
    del call
    gc.collect()
    assert a() is None


def test_arrays_a_table_cannot_hold_are_refused_by_name() -> None:
    with pytest.raises(ParameterError) as error:
        ArrayTable([np.zeros(3), np.zeros(8)[::2]], ("wrench", "q"))
    assert str(error.value) == "array table: q is not C-contiguous (a strided view?)"
    with pytest.raises(ParameterError) as error:
        ArrayTable([np.zeros((1, 1, 1, 1))], ("poses",))
    assert str(error.value) == "array table: poses has 4 dimensions, not 1 to 3"
    with pytest.raises(ParameterError) as error:
        ArrayTable([np.zeros(2), [1.0, 2.0]])  # type: ignore[list-item]
    assert str(error.value) == "array table: array 1 is a list, not an array"


def test_an_entry_is_refused_a_table_of_other_arrays() -> None:
    arrays = (np.zeros(2), np.zeros((2, 2)), np.zeros((1, 1, 1), np.uint8), np.zeros(1, RECORD))
    with pytest.raises(ParameterError) as error:
        ArrayTable(arrays).bind(entry, LAYOUT, last=(0,))
    assert str(error.value) == (
        "array table: arrays (<f8/1d, <f8/2d, |u1/3d, |V56/1d) given to an entry that takes "
        "(<f8/1d, <i8/2d, |u1/3d, |V56/1d)"
    )
