"""The latency histogram: its compiled add against numpy's own quantiles, sums and maximum."""

import math
import pickle

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.rig.loop_figures import LoopSummary
from hilrig.timing import LatencyHistogram

MAX_US = 50
durations = st.lists(st.integers(-5_000, 80_000), min_size=1, max_size=300)


def oracle_quantile_us(values_ns: list[int], q: float) -> float:
    """The smallest 1 us bin (clamped to 0..MAX_US) holding at least q of the values."""
    bins = np.clip(np.floor_divide(values_ns, 1000), 0, MAX_US)
    rank = max(math.ceil(q * len(bins)), 1)
    return float(np.sort(bins)[rank - 1])


@settings(max_examples=200, deadline=None)
@given(durations, st.sampled_from([0.01, 0.5, 0.9, 0.99, 0.999, 1.0]))
def test_quantiles_count_sum_and_max_match_numpy(values: list[int], q: float) -> None:
    histogram = LatencyHistogram(max_us=MAX_US)
    for value in values:
        histogram.add(value)
    assert histogram.count == len(values)
    assert histogram.total_ns == sum(values)
    assert histogram.max_ns == max(0, *values)
    assert histogram.quantile_us(q) == oracle_quantile_us(values, q)
    bins = np.clip(np.floor_divide(values, 1000), 0, MAX_US)
    np.testing.assert_array_equal(histogram.counts(), np.bincount(bins, minlength=MAX_US + 1))


def test_an_empty_histogram_has_no_quantiles_and_a_copy_keeps_counting() -> None:
    histogram = LatencyHistogram()
    assert math.isnan(histogram.quantile_us(0.5)) and math.isnan(histogram.summary_us()["mean"])
    histogram.add(1_500)
    copy = pickle.loads(pickle.dumps(histogram))  # e.g. a summary sent to another process
    copy.add(2_500)
    assert (histogram.count, copy.count) == (1, 2)
    assert copy.summary_us() == {"mean": 2.0, "p50": 1.0, "p99": 2.0, "p99.9": 2.0, "max": 2.5}


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(*[st.integers(-5_000, 30_000_000)] * 4), min_size=1, max_size=100))
def test_a_periods_four_durations_land_in_their_own_histograms(
    periods: list[tuple[int, int, int, int]],
) -> None:
    summary = LoopSummary()
    add = summary.period_adder()
    for period in periods:
        add(*period)
    for column, histogram in enumerate(
        (summary.io, summary.compute, summary.send, summary.lateness)
    ):
        values = [period[column] for period in periods]
        alone = LatencyHistogram()  # the same durations, one add each
        for value in values:
            alone.add(value)
        assert histogram.count == len(values)
        assert histogram.total_ns == sum(values)
        assert histogram.max_ns == max(0, *values)
        np.testing.assert_array_equal(histogram.counts(), alone.counts())
    assert summary.sensor_to_command.count == 0
