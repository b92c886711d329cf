"""Display decimation against a plain numpy oracle and its invariants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hilrig.errors import ViewError
from hilrig.viz import minmax_indices, peak_indices

finite = st.floats(-1e6, 1e6, allow_nan=False)
with_nan = st.one_of(finite, st.just(float("nan")))


def bounds(n: int, buckets: int) -> list[tuple[int, int]]:
    return [((b * n) // buckets, ((b + 1) * n) // buckets) for b in range(buckets)]


def oracle_minmax(values: np.ndarray, max_points: int) -> np.ndarray:
    """Per bucket: numpy's nanargmin and nanargmax (first occurrence), sorted, deduplicated."""
    out: list[int] = []
    for lo, hi in bounds(len(values), max_points // 2):
        chunk = values[lo:hi]
        if np.all(np.isnan(chunk)):
            out.append(lo)
            continue
        out.extend(sorted({lo + int(np.nanargmin(chunk)), lo + int(np.nanargmax(chunk))}))
    return np.asarray(out)


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(0, 400), elements=with_nan), st.integers(2, 60))
def test_minmax_matches_the_oracle(values: np.ndarray, max_points: int) -> None:
    got = minmax_indices(values, max_points)
    if len(values) <= max_points:
        np.testing.assert_array_equal(got, np.arange(len(values)))
    else:
        np.testing.assert_array_equal(got, oracle_minmax(values, max_points))


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(1, 2000), elements=finite), st.integers(2, 200))
def test_minmax_keeps_the_extremes_in_time_order_within_budget(
    values: np.ndarray, max_points: int
) -> None:
    got = minmax_indices(values, max_points)
    assert len(got) <= max(max_points, 1)
    assert np.all(np.diff(got) > 0)
    assert values[got].max() == values.max()
    assert values[got].min() == values.min()


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(0, 400), elements=with_nan), st.integers(1, 60))
def test_peaks_match_the_oracle(magnitude: np.ndarray, max_points: int) -> None:
    got = peak_indices(magnitude, max_points)
    if len(magnitude) <= max_points:
        np.testing.assert_array_equal(got, np.arange(len(magnitude)))
        return
    expected = []
    for lo, hi in bounds(len(magnitude), max_points):
        chunk = magnitude[lo:hi]
        expected.append(lo if np.all(np.isnan(chunk)) else lo + int(np.nanargmax(chunk)))
    np.testing.assert_array_equal(got, expected)


def test_zero_means_every_sample() -> None:
    values = np.arange(10.0)
    np.testing.assert_array_equal(minmax_indices(values, 0), np.arange(10))
    np.testing.assert_array_equal(peak_indices(values, 0), np.arange(10))


def test_a_single_spike_survives_heavy_decimation() -> None:
    values = np.zeros(1_000_000)
    values[654_321] = 7.5
    got = minmax_indices(values, 100)
    assert 654_321 in got
    assert len(got) <= 100


@pytest.mark.parametrize("function", [minmax_indices, peak_indices])
def test_negative_budget_is_refused(function: object) -> None:
    with pytest.raises(ViewError) as err:
        function(np.zeros(3), -1)  # type: ignore[operator]
    assert str(err.value) == "max_points -1 must be >= 0"
