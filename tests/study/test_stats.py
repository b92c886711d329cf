"""Statistics across volunteers (hilrig.study.stats) against independent oracles: hand-computed
cases, scipy called directly, pandas/numpy computed another way (properties:
test_stats_properties.py)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps
from stats_helpers import observations_of, only_row, values_table

from hilrig.errors import AnalysisError
from hilrig.study.records import (
    COMPARISON_COLUMNS,
    DISTRIBUTION_COLUMNS,
    SUBJECT_COLUMNS,
)
from hilrig.study.stats import comparisons, design, distributions, subject_values

# Nothing here may warn: scipy's warnings are caught inside the module.
pytestmark = pytest.mark.filterwarnings("error")

FAST = {"resamples": 999}


# ---------------------------------------------------------------------- subject values


def test_subject_values_means_skip_nan_and_drop_empty_groups() -> None:
    nan = float("nan")
    obs = observations_of(
        [
            ("S2", "adaptive", 0, "peak_force", 10.0),
            ("S2", "adaptive", 1, "peak_force", 14.0),
            ("S2", "adaptive", 2, "peak_force", nan),
            ("S1", "adaptive", 0, "peak_force", 3.0),
            ("S1", "fixed", 0, "peak_force", 5.0),
            ("S1", "fixed", 1, "peak_force", 6.0),
            ("S1", "fixed", 0, "recovery_time_s", nan),  # no value at all: dropped
            ("S1", "fixed", 1, "recovery_time_s", nan),
            ("S1", "fixed", 0, "zz_custom", 1.0),
            ("S1", "fixed", 0, "aa_custom", 2.0),
            ("S1", "fixed", 0, "impulse", 0.5),
        ]
    )
    table = subject_values(obs)
    assert tuple(table.columns) == SUBJECT_COLUMNS
    # Oracle: plain Python over the rows.
    expected: dict[tuple[str, str, str], list[float]] = {}
    for s, c, m, v in obs[["subject", "condition", "metric", "value"]].itertuples(index=False):
        if not math.isnan(v):
            expected.setdefault((s, c, m), []).append(v)
    got = {
        (r.subject, r.condition, r.metric): (r.value, r.events)
        for r in table.itertuples(index=False)
    }
    assert got == {k: (sum(v) / len(v), len(v)) for k, v in expected.items()}
    # Order: metric in STUDY_METRICS order, unknown metrics after alphabetically; condition
    # first seen (adaptive before fixed); subject.
    order = list(zip(table["metric"], table["condition"], table["subject"], strict=True))
    assert order == [
        ("peak_force", "adaptive", "S1"),
        ("peak_force", "adaptive", "S2"),
        ("peak_force", "fixed", "S1"),
        ("impulse", "fixed", "S1"),
        ("aa_custom", "fixed", "S1"),
        ("zz_custom", "fixed", "S1"),
    ]
    assert table["events"].dtype == np.int64


def test_subject_values_groups_sorted_first() -> None:
    obs = observations_of([("S1", "a", 0, "peak_force", 1.0)])
    joint = obs.assign(group="joint", axis="joint2", value=2.0)
    table = subject_values(pd.concat([joint, obs], ignore_index=True))
    assert list(table["group"]) == ["cartesian", "joint"]


# ---------------------------------------------------------------------- distributions


def test_distributions_against_pandas() -> None:
    table = pd.concat(
        [
            values_table({"fixed": {"S1": 1.0, "S2": 4.0, "S3": 2.0, "S4": 10.0}}),
            values_table({"adaptive": {"S1": 7.0}}),  # one subject: sd NaN
            values_table({"fixed": {"S1": 0.5, "S2": 1.5}}, metric="impulse"),
        ],
        ignore_index=True,
    )
    table.loc[1, "events"] = 3
    got = distributions(table)
    assert tuple(got.columns) == DISTRIBUTION_COLUMNS
    grouped = table.groupby(["group", "metric", "condition"], sort=False)
    oracle = grouped.agg(
        subjects=("value", "size"),
        events=("events", "sum"),
        median=("value", "median"),
        q1=("value", lambda v: v.quantile(0.25)),
        q3=("value", lambda v: v.quantile(0.75)),
        mean=("value", "mean"),
        sd=("value", "std"),
        min=("value", "min"),
        max=("value", "max"),
    ).reset_index()
    pd.testing.assert_frame_equal(got, oracle.loc[:, list(DISTRIBUTION_COLUMNS)])
    fixed = got.iloc[0]
    assert (fixed["q1"], fixed["median"], fixed["q3"]) == (1.75, 3.0, 5.5)
    assert fixed["sd"] == pytest.approx(np.sqrt(((np.array([1, 4, 2, 10]) - 4.25) ** 2).sum() / 3))
    assert fixed["events"] == 6
    assert math.isnan(got.iloc[1]["sd"])
    assert list(got["metric"]) == ["peak_force", "peak_force", "impulse"]


# ---------------------------------------------------------------------- hand cases


def signed_rank_p(d: list[float]) -> float:
    """Exact two-sided Wilcoxon p by enumerating every sign pattern (distinct |d|, no zeros)."""
    ranks = sps.rankdata(np.abs(d))
    observed = ranks[np.asarray(d) > 0].sum()
    low = min(observed, ranks.sum() - observed)
    patterns = list(itertools.product([0, 1], repeat=len(d)))
    below = sum(1 for p in patterns if np.dot(p, ranks) <= low)
    return min(1.0, 2 * below / len(patterns))


def test_paired_hand_case() -> None:
    baseline = {"S1": 10.0, "S2": 12.0, "S3": 9.0, "S4": 11.0, "S5": 8.0}
    d = {"S1": 1.0, "S2": -2.0, "S3": 3.0, "S4": 4.0, "S5": 5.0}
    condition = {s: baseline[s] + d[s] for s in baseline}
    row = only_row(comparisons(values_table({"fixed": baseline, "adaptive": condition}), "fixed"))
    assert (row["design"], row["test"]) == ("paired", "wilcoxon")
    assert (row["n_baseline"], row["n_condition"], row["left_out"]) == (5, 5, 0)
    assert row["median_baseline"] == 10.0
    assert row["median_condition"] == 12.0  # of 11, 10, 12, 15, 13
    assert row["median_difference"] == 3.0  # median of 1, -2, 3, 4, 5
    # Ranks of |d| are 1..5; R- = 2 (the -2), R+ = 13; the two-sided statistic is min = 2.
    assert row["statistic"] == 2.0
    # Sign patterns with R+ <= 2: {}, {1}, {2}: 3 of 32, two-sided 6/32.
    assert row["p_value"] == pytest.approx(6 / 32)
    assert row["p_value"] == pytest.approx(signed_rank_p(list(d.values())))
    assert row["effect_size"] == pytest.approx((13 - 2) / 15)
    assert row["ci_low"] <= row["median_difference"] <= row["ci_high"]


def test_unpaired_hand_case() -> None:
    condition = {"C1": 3.0, "C2": 5.0, "C3": 7.0}
    baseline = {"B1": 1.0, "B2": 2.0, "B3": 4.0, "B4": 6.0}
    row = only_row(comparisons(values_table({"fixed": baseline, "adaptive": condition}), "fixed"))
    assert (row["design"], row["test"]) == ("unpaired", "mann-whitney")
    assert (row["n_baseline"], row["n_condition"], row["left_out"]) == (4, 3, 0)
    assert row["median_difference"] == 5.0 - 3.0
    # U of the condition: pairs (c, b) with c > b: 3 -> 2, 5 -> 3, 7 -> 4.
    assert row["statistic"] == 9.0
    assert row["effect_size"] == pytest.approx(2 * 9 / 12 - 1)
    # Exact p: every way the condition could hold 3 of the 7 ranks; U = rank sum - 6.
    us = [sum(r) - 6 for r in itertools.combinations(range(1, 8), 3)]
    p = 2 * sum(u >= 9 for u in us) / len(us)
    assert row["p_value"] == pytest.approx(p)


# ---------------------------------------------------------------------- against scipy


def test_paired_against_scipy_with_left_out_subjects() -> None:
    rng = np.random.default_rng(3)
    common = [f"S{i}" for i in range(7)]
    baseline = {s: float(v) for s, v in zip(common, rng.normal(10, 2, 7), strict=True)}
    condition = {
        s: baseline[s] + float(v) for s, v in zip(common, rng.normal(1, 1, 7), strict=True)
    }
    baseline["only_b"] = 100.0
    condition["only_c1"], condition["only_c2"] = -100.0, 50.0
    table = values_table({"fixed": baseline, "adaptive": condition})
    row = only_row(comparisons(table, "fixed", **FAST))
    assert (row["design"], row["n_baseline"], row["n_condition"], row["left_out"]) == (
        "paired",
        7,
        7,
        3,
    )
    d = np.array([condition[s] - baseline[s] for s in common])
    ref = sps.wilcoxon(d)
    assert row["statistic"] == ref.statistic
    assert row["p_value"] == pytest.approx(ref.pvalue)
    assert row["median_difference"] == pytest.approx(np.median(d))
    assert row["median_baseline"] == pytest.approx(np.median([baseline[s] for s in common]))
    ci = sps.bootstrap(
        (d,),
        np.median,
        n_resamples=999,
        method="percentile",
        random_state=np.random.default_rng(0),
    ).confidence_interval
    assert (row["ci_low"], row["ci_high"]) == pytest.approx((ci.low, ci.high))


def test_unpaired_against_scipy() -> None:
    c = np.array([3.1, 4.7, 2.2, 8.0, 5.5])
    b = np.array([1.0, 2.5, 0.3, 4.4, 2.2, 3.3])
    table = values_table(
        {
            "fixed": {f"B{i}": v for i, v in enumerate(b)},
            "adaptive": {f"C{i}": v for i, v in enumerate(c)},
        }
    )
    row = only_row(comparisons(table, "fixed", confidence=0.9, seed=7, **FAST))
    ref = sps.mannwhitneyu(c, b, alternative="two-sided")
    assert row["statistic"] == ref.statistic
    assert row["p_value"] == pytest.approx(ref.pvalue)
    assert row["effect_size"] == pytest.approx(2 * ref.statistic / (5 * 6) - 1)
    ci = sps.bootstrap(
        (c, b),
        lambda x, y, axis: np.median(x, axis=axis) - np.median(y, axis=axis),
        confidence_level=0.9,
        n_resamples=999,
        method="percentile",
        random_state=np.random.default_rng(7),
    ).confidence_interval
    assert (row["ci_low"], row["ci_high"]) == pytest.approx((ci.low, ci.high))


def test_benjamini_hochberg_against_scipy_and_row_order() -> None:
    rng = np.random.default_rng(1)
    parts = []
    for group, metric in [
        ("joint", "impulse"),
        ("cartesian", "margin_pct"),
        ("cartesian", "impulse"),
    ]:
        samples = {}
        for condition, shift in [("slow", 0.5), ("fixed", 0.0), ("fast", 2.0)]:
            samples[condition] = {f"S{i}": float(v) for i, v in enumerate(rng.normal(shift, 1, 6))}
        parts.append(values_table(samples, metric=metric, group=group))
    parts.append(values_table({"fast": {"S0": 1.0}}, metric="peak_force"))  # no test: NaN p
    table = comparisons(pd.concat(parts, ignore_index=True), "fixed", **FAST)
    assert tuple(table.columns) == COMPARISON_COLUMNS
    keys = list(zip(table["group"], table["metric"], table["condition"], strict=True))
    assert keys == [
        ("cartesian", "peak_force", "fast"),
        ("cartesian", "impulse", "slow"),
        ("cartesian", "impulse", "fast"),
        ("cartesian", "margin_pct", "slow"),
        ("cartesian", "margin_pct", "fast"),
        ("joint", "impulse", "slow"),
        ("joint", "impulse", "fast"),
    ]
    assert (table["baseline"] == "fixed").all()
    finite = table["p_value"].notna()
    assert finite.sum() == 6
    expected = sps.false_discovery_control(table.loc[finite, "p_value"].to_numpy())
    np.testing.assert_allclose(table.loc[finite, "p_adjusted"], expected)
    assert table.loc[~finite, "p_adjusted"].isna().all()


# ---------------------------------------------------------------------- edge cases


def test_one_subject_each_gives_medians_and_nan_statistics() -> None:
    table = values_table({"fixed": {"S1": 2.0}, "adaptive": {"S1": 5.0}})
    row = only_row(comparisons(table, "fixed"))
    assert (row["design"], row["test"], row["left_out"]) == ("unpaired", "mann-whitney", 0)
    assert (row["median_baseline"], row["median_condition"], row["median_difference"]) == (
        2.0,
        5.0,
        3.0,
    )
    for column in ("ci_low", "ci_high", "statistic", "p_value", "p_adjusted", "effect_size"):
        assert math.isnan(row[column]), column


def test_baseline_without_values_for_a_metric() -> None:
    table = pd.concat(
        [
            values_table({"fixed": {"S1": 1.0, "S2": 2.0}, "adaptive": {"S1": 2.0, "S2": 4.0}}),
            values_table({"adaptive": {"S1": 2.0, "S2": 4.0}}, metric="recovery_time_s"),
        ],
        ignore_index=True,
    )
    row = comparisons(table, "fixed", **FAST).iloc[1]
    assert (row["metric"], row["design"], row["n_baseline"], row["n_condition"]) == (
        "recovery_time_s",
        "unpaired",
        0,
        2,
    )
    assert row["median_condition"] == 3.0
    assert math.isnan(row["median_baseline"]) and math.isnan(row["median_difference"])
    assert math.isnan(row["p_value"])


def test_all_zero_differences() -> None:
    same = {"S1": 1.0, "S2": 3.0, "S3": 2.0}
    row = only_row(comparisons(values_table({"fixed": same, "adaptive": dict(same)}), "fixed"))
    assert (row["design"], row["test"]) == ("paired", "wilcoxon")
    assert (row["median_difference"], row["ci_low"], row["ci_high"]) == (0.0, 0.0, 0.0)
    for column in ("statistic", "p_value", "p_adjusted", "effect_size"):
        assert math.isnan(row[column]), column


def test_degenerate_bootstrap_gives_the_estimate() -> None:
    paired = values_table({"fixed": {"S1": 1.0, "S2": 2.0}, "adaptive": {"S1": 3.0, "S2": 4.0}})
    row = only_row(comparisons(paired, "fixed"))
    assert (row["median_difference"], row["ci_low"], row["ci_high"]) == (2.0, 2.0, 2.0)
    assert row["effect_size"] == 1.0
    assert row["p_value"] == pytest.approx(sps.wilcoxon([2.0, 2.0]).pvalue)
    unpaired = values_table({"fixed": {"A": 1.0, "B": 1.0}, "adaptive": {"C": 4.0, "D": 4.0}})
    row = only_row(comparisons(unpaired, "fixed"))
    assert (row["median_difference"], row["ci_low"], row["ci_high"]) == (3.0, 3.0, 3.0)
    assert row["effect_size"] == 1.0


def test_missing_baseline_is_refused_with_the_conditions() -> None:
    table = values_table({"fixed": {"S1": 1.0}, "adaptive": {"S1": 2.0}})
    message = "baseline 'none' is not a condition here; conditions: fixed, adaptive"
    with pytest.raises(AnalysisError) as error:
        comparisons(table, "none")
    assert str(error.value) == message
    obs = observations_of(
        [("S1", "fixed", 0, "impulse", 1.0), ("S1", "adaptive", 0, "impulse", 2.0)]
    )
    with pytest.raises(AnalysisError) as error:
        design(obs, "none")
    assert str(error.value) == message


# ---------------------------------------------------------------------- design


def test_design_table_and_sentences() -> None:
    rows = []
    for s in ["S1", "S2", "S3", "S4"]:
        for c in ["adaptive", "fixed"]:
            rows += [(s, c, e, m, 1.0) for e in range(2) for m in ("peak_force", "impulse")]
    rows += [("S5", "fixed", 0, "peak_force", 1.0), ("S6", "soft", 0, "peak_force", 1.0)]
    rows += [("S7", "soft", 0, "peak_force", 1.0), ("S8", "stiff", 0, "peak_force", 1.0)]
    rows += [("S1", "stiff", 0, "peak_force", 1.0), ("S9", "stiff", 0, "peak_force", 1.0)]
    obs = observations_of(rows)
    obs.loc[obs["subject"] == "S1", "session"] = "S1-day1"  # one session, two conditions
    table, text = design(obs, "fixed")
    assert list(table.columns) == ["condition", "subjects", "sessions", "events"]
    assert list(table["condition"]) == ["fixed", "adaptive", "soft", "stiff"]
    assert list(table["subjects"]) == [5, 4, 2, 3]
    assert list(table["sessions"]) == [5, 4, 2, 3]
    # Events are distinct (session, event) pairs: S1's two conditions share one session.
    oracle = [
        len({(r.session, r.event) for r in obs.itertuples() if r.condition == c})
        for c in table["condition"]
    ]
    assert list(table["events"]) == oracle
    assert text == (
        "adaptive vs fixed: 4 subjects saw both (paired on them); "
        "1 saw only one and is left out of that comparison",
        "soft vs fixed: no subject saw both (unpaired, between-subject: 2 and 5 subjects)",
        "stiff vs fixed: only 1 subject saw both (unpaired, between-subject: 3 and 5 subjects)",
    )
    _, text = design(obs[obs["subject"] != "S5"], "adaptive")
    assert text[0] == "fixed vs adaptive: 4 subjects saw both (paired, within-subject)"
