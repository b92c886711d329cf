"""Properties of the statistics across volunteers (hilrig.study.stats), by hypothesis: swapping
the roles of condition and baseline, when a comparison is paired, a shifted copy."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stats_helpers import observations_of, only_row, values_table

from hilrig.study.stats import comparisons, design

# Nothing here may warn: scipy's warnings are caught inside the module.
pytestmark = pytest.mark.filterwarnings("error")

value = st.one_of(
    st.integers(-3, 3).map(float),
    st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False),
)
# Per subject: a value under "a", under "b", or under both (None: not seen).
subjects = st.lists(
    st.tuples(st.none() | value, st.none() | value).filter(lambda p: p != (None, None)),
    min_size=1,
    max_size=9,
)


def two_conditions(pairs: list[tuple[float | None, float | None]], metric: str) -> pd.DataFrame:
    samples: dict[str, dict[str, float]] = {"a": {}, "b": {}}
    for i, (a, b) in enumerate(pairs):
        if a is not None:
            samples["a"][f"S{i}"] = a
        if b is not None:
            samples["b"][f"S{i}"] = b
    return values_table(samples, metric=metric)


both_seen = subjects.filter(
    lambda p: any(a is not None for a, _ in p) and any(b is not None for _, b in p)
)


@settings(max_examples=60, deadline=None)
@given(both_seen, both_seen)
def test_swapping_roles_negates_the_difference_and_keeps_p(first: list, second: list) -> None:
    table = pd.concat(
        [two_conditions(first, "peak_force"), two_conditions(second, "impulse")],
        ignore_index=True,
    )
    ab = comparisons(table, "b", resamples=199)
    ba = comparisons(table, "a", resamples=199)
    assert list(ab["design"]) == list(ba["design"])
    np.testing.assert_array_equal(ab["median_difference"], -ba["median_difference"])
    np.testing.assert_allclose(ab["effect_size"], -ba["effect_size"], atol=1e-12)
    np.testing.assert_allclose(ab["p_value"], ba["p_value"], rtol=1e-9)
    np.testing.assert_allclose(ab["p_adjusted"], ba["p_adjusted"], rtol=1e-9)
    for table in (ab, ba):
        p, q = table["p_value"], table["p_adjusted"]
        assert (p.isna() == q.isna()).all()
        finite = p.notna()
        assert ((p[finite] >= 0) & (p[finite] <= q[finite]) & (q[finite] <= 1)).all()
        ci = table[table["ci_low"].notna()]
        assert (ci["ci_low"] <= ci["ci_high"]).all()
        effect = table["effect_size"].dropna()
        assert ((effect >= -1) & (effect <= 1)).all()


@settings(max_examples=60, deadline=None)
@given(both_seen)
def test_paired_iff_two_common_subjects(pairs: list) -> None:
    common = sum(a is not None and b is not None for a, b in pairs)
    row = only_row(comparisons(two_conditions(pairs, "peak_force"), "b", resamples=199))
    assert (row["design"] == "paired") == (common >= 2)
    only = sum((a is None) != (b is None) for a, b in pairs)
    assert row["left_out"] == (only if common >= 2 else 0)
    rows = [
        (f"S{i}", c, 0, "peak_force", 1.0)
        for i, pair in enumerate(pairs)
        for c, v in zip("ab", pair, strict=True)
        if v is not None
    ]
    _, text = design(observations_of(rows), "b")
    assert ("(paired" in text[0]) == (common >= 2)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.integers(-1000, 1000).map(float), min_size=2, max_size=8),
    st.integers(1, 50).map(float),
)
def test_shifted_copy(baseline: list[float], shift: float) -> None:
    samples = {
        "fixed": {f"S{i}": v for i, v in enumerate(baseline)},
        "shifted": {f"S{i}": v + shift for i, v in enumerate(baseline)},
    }
    row = only_row(comparisons(values_table(samples), "fixed", resamples=199))
    assert row["design"] == "paired"
    assert row["median_difference"] == shift
    assert (row["ci_low"], row["ci_high"]) == (shift, shift)
    assert row["effect_size"] == 1.0
    assert 0 < row["p_value"] <= 1
