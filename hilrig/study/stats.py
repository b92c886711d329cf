"""Statistics across volunteers: subject values, their distributions and each condition
against a baseline (docs/study.md, "Statistics").

The unit of analysis is the subject: a subject's value of a metric under a condition is the
mean over that subject's events (NaN values skipped), so a subject with many events weighs no
more than one with few.

Design rule, per group and metric: the subjects who have values under both the condition and
the baseline are *paired* when there are at least 2 of them; the paired test runs on them only
and the subjects who have just one of the two are counted in ``left_out``. With fewer than 2
common subjects the comparison is *unpaired*, on every subject of each condition.

Choices:

- Paired: differences ``d = condition - baseline`` per subject; Wilcoxon signed-rank test,
  two-sided, ``zero_method="wilcox"`` (zero differences are discarded, the classic convention;
  all zero leaves nothing to test: statistic, p and effect size NaN). Effect size: the
  matched-pairs rank-biserial correlation ``(R+ - R-) / (R+ + R-)`` on the ranks of the nonzero
  ``|d|`` (ties averaged), consistent with the discarded zeros. p-values by scipy's
  ``method="auto"``: exact up to 50 differences without ties or zeros; with them, an exhaustive
  permutation up to 13 (~1 s at 13), the normal approximation beyond. ``median_baseline`` and
  ``median_condition`` are then the paired subjects' medians.
- Unpaired: Mann-Whitney U test, two-sided, U of the condition; effect size the rank-biserial
  correlation ``2U / (n1 n2) - 1`` (positive: condition larger). Fewer than 2 values on either
  side: the medians are given, every statistic (CI included) is NaN.
- Confidence intervals: bootstrap of the median difference with the *percentile* method.
  BCa corrects its bias with the fraction of resamples below the estimate, which a median of a
  handful of subjects (a discrete bootstrap distribution with many ties at the estimate)
  biases, and its jackknife acceleration is crude for a median; the percentile interval is
  stable there and gives ``ci_low = ci_high = estimate`` when every value is equal.
- ``p_adjusted``: Benjamini-Hochberg (:func:`scipy.stats.false_discovery_control`) over every
  finite p-value of the table; NaN stays NaN.

Nothing here raises for lack of data or warns: scipy's warnings are caught locally and a test
scipy cannot compute gives NaN.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from hilrig.errors import AnalysisError
from hilrig.study.records import (
    COMPARISON_COLUMNS,
    DISTRIBUTION_COLUMNS,
    STUDY_METRICS,
    SUBJECT_COLUMNS,
    FloatArray,
)

PAIRED = "paired"
UNPAIRED = "unpaired"
WILCOXON = "wilcoxon"
MANN_WHITNEY = "mann-whitney"
_NAN = float("nan")


def _metric_order(metrics: Iterable[str]) -> dict[str, int]:
    """Sort keys: STUDY_METRICS order, unknown metrics after, alphabetically."""
    extra = sorted(set(metrics) - set(STUDY_METRICS))
    return {m: i for i, m in enumerate([*STUDY_METRICS, *extra])}


def _first_seen(values: pd.Series[Any]) -> list[str]:
    return [str(v) for v in dict.fromkeys(values)]


def _ordered(table: pd.DataFrame, conditions: Sequence[str], last: Sequence[str]) -> pd.DataFrame:
    """``table`` sorted by group, metric (study order), condition (``conditions``), ``last``."""
    keys = {
        "_metric": table["metric"].map(_metric_order(table["metric"])),
        "_condition": table["condition"].map({c: i for i, c in enumerate(conditions)}),
    }
    table = table.assign(**keys)
    table = table.sort_values(["group", "_metric", "_condition", *last], kind="stable")
    return table.drop(columns=list(keys)).reset_index(drop=True)


def subject_values(observations: pd.DataFrame) -> pd.DataFrame:
    """Per subject, condition, group and metric the mean ``value`` over the subject's events
    (NaN skipped) and ``events``, how many values it averages; groups without a value dropped.
    Rows by group, metric (study order), condition (first seen), subject."""
    keys = ["subject", "condition", "group", "metric"]
    grouped = observations.groupby(keys, sort=False)["value"]
    table = grouped.agg(value="mean", events="count").reset_index()
    table = table.loc[table["events"] > 0].astype({"value": np.float64, "events": np.int64})
    ordered = _ordered(table, _first_seen(observations["condition"]), ["subject"])
    return ordered.loc[:, list(SUBJECT_COLUMNS)]


def _describe(values: FloatArray, events: int) -> dict[str, float | int]:
    q1, median, q3 = np.percentile(values, [25.0, 50.0, 75.0])
    return {
        "subjects": len(values),
        "events": events,
        "median": float(median),
        "q1": float(q1),
        "q3": float(q3),
        "mean": float(np.mean(values)),
        "sd": float(np.std(values, ddof=1)) if len(values) > 1 else _NAN,
        "min": float(np.min(values)),
        "max": float(np.max(values)),
    }


def distributions(subject_values: pd.DataFrame) -> pd.DataFrame:
    """Per group, metric and condition the distribution of the subject values: subjects,
    events (sum), median, quartiles (numpy's linear percentiles), mean, sd (ddof=1; NaN for one
    subject), min and max. Rows by group, metric (study order), condition (first seen)."""
    keys = ["group", "metric", "condition"]
    rows = [
        dict(zip(keys, key, strict=True))
        | _describe(part["value"].to_numpy(np.float64), int(part["events"].sum()))
        for key, part in subject_values.groupby(keys, sort=False)
    ]
    table = pd.DataFrame(rows, columns=list(DISTRIBUTION_COLUMNS))
    table = table.astype({"subjects": np.int64, "events": np.int64})
    return _ordered(table, _first_seen(subject_values["condition"]), [])


def _quiet(call: Callable[[], Any]) -> Any:
    """``call()`` with scipy's runtime warnings (degenerate or small data) silenced; None if
    scipy refuses the data (ValueError)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # DegenerateDataWarning is one
        try:
            return call()
        except ValueError:
            return None


def _bootstrap(
    data: tuple[FloatArray, ...],
    statistic: Callable[..., Any],
    estimate: float,
    confidence: float,
    resamples: int,
    seed: int,
) -> tuple[float, float]:
    """Percentile bootstrap interval of ``statistic``; (estimate, estimate) when every value
    is equal in each sample."""
    if all(np.ptp(sample) == 0 for sample in data):
        return estimate, estimate
    result = _quiet(
        lambda: stats.bootstrap(
            data,
            statistic,
            confidence_level=confidence,
            n_resamples=resamples,
            method="percentile",
            random_state=np.random.default_rng(seed),
        )
    )
    if result is None:
        return _NAN, _NAN
    return float(result.confidence_interval.low), float(result.confidence_interval.high)


def _median_difference(x: FloatArray, y: FloatArray, axis: int = -1) -> Any:
    return np.median(x, axis=axis) - np.median(y, axis=axis)


def _paired(d: FloatArray, confidence: float, resamples: int, seed: int) -> dict[str, float | str]:
    """Wilcoxon signed-rank on the differences, with the matched-pairs rank-biserial."""
    estimate = float(np.median(d))
    ci = _bootstrap((d,), np.median, estimate, confidence, resamples, seed)
    row: dict[str, float | str] = {"median_difference": estimate, "ci_low": ci[0]}
    row |= {"ci_high": ci[1], "test": WILCOXON, "statistic": _NAN, "p_value": _NAN}
    nonzero = d[d != 0]
    if len(nonzero) == 0:
        return row | {"effect_size": _NAN}
    result = _quiet(lambda: stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided"))
    if result is not None:
        row |= {"statistic": float(result.statistic), "p_value": float(result.pvalue)}
    ranks = stats.rankdata(np.abs(nonzero))
    signed = float(np.sum(ranks[nonzero > 0]) - np.sum(ranks[nonzero < 0]))
    return row | {"effect_size": signed / float(np.sum(ranks))}


def _unpaired(
    condition: FloatArray, baseline: FloatArray, confidence: float, resamples: int, seed: int
) -> dict[str, float | str]:
    """Mann-Whitney U (the condition's), with the rank-biserial 2U/(n1 n2) - 1."""
    row: dict[str, float | str] = {"median_difference": _NAN, "ci_low": _NAN, "ci_high": _NAN}
    row |= {"test": MANN_WHITNEY, "statistic": _NAN, "p_value": _NAN, "effect_size": _NAN}
    if len(condition) and len(baseline):
        row["median_difference"] = float(np.median(condition) - np.median(baseline))
    if len(condition) < 2 or len(baseline) < 2:
        return row
    estimate = float(row["median_difference"])
    data = (condition, baseline)
    ci = _bootstrap(data, _median_difference, estimate, confidence, resamples, seed)
    row |= {"ci_low": ci[0], "ci_high": ci[1]}
    result = _quiet(lambda: stats.mannwhitneyu(condition, baseline, alternative="two-sided"))
    if result is not None:
        u = float(result.statistic)
        row |= {"statistic": u, "p_value": float(result.pvalue)}
        row["effect_size"] = 2.0 * u / (len(condition) * len(baseline)) - 1.0
    return row


def _median(values: FloatArray) -> float:
    return float(np.median(values)) if len(values) else _NAN


def _compare(
    condition: pd.Series[float],
    baseline: pd.Series[float],
    confidence: float,
    resamples: int,
    seed: int,
) -> dict[str, float | int | str]:
    """One comparison; ``condition`` and ``baseline`` are subject values indexed by subject."""
    common = condition.index.intersection(baseline.index)
    left_out = len(condition.index.union(baseline.index)) - len(common)
    paired = len(common) >= 2
    if paired:
        condition, baseline = condition.loc[common], baseline.loc[common]
    c = np.asarray(condition, dtype=np.float64)
    b = np.asarray(baseline, dtype=np.float64)
    if paired:
        head: dict[str, float | int | str] = {"design": PAIRED, "left_out": left_out}
        tail = _paired(c - b, confidence, resamples, seed)
    else:
        head = {"design": UNPAIRED, "left_out": 0}
        tail = _unpaired(c, b, confidence, resamples, seed)
    head |= {"n_baseline": len(b), "n_condition": len(c)}
    return head | {"median_baseline": _median(b), "median_condition": _median(c)} | tail


def _adjusted(p: FloatArray) -> FloatArray:
    """Benjamini-Hochberg over the finite p-values; NaN stays NaN."""
    adjusted = np.full(len(p), np.nan)
    finite = np.isfinite(p)
    if finite.any():
        adjusted[finite] = stats.false_discovery_control(p[finite], method="bh")
    return adjusted


def _missing_baseline(baseline: str, conditions: Sequence[str]) -> AnalysisError:
    listed = ", ".join(conditions) or "none"
    return AnalysisError(f"baseline {baseline!r} is not a condition here; conditions: {listed}")


def comparisons(
    subject_values: pd.DataFrame,
    baseline: str,
    *,
    confidence: float = 0.95,
    resamples: int = 9999,
    seed: int = 0,
) -> pd.DataFrame:
    """Every condition against ``baseline`` per group and metric (COMPARISON_COLUMNS): paired
    Wilcoxon or unpaired Mann-Whitney by the design rule, bootstrap CI of the median difference,
    rank-biserial effect size and Benjamini-Hochberg ``p_adjusted`` over the table. A condition
    gets a row where it has subject values (the baseline may have none there: NaN statistics).
    Rows by group, metric (study order), condition (first seen). Raises AnalysisError if
    ``baseline`` is not a condition of ``subject_values``."""
    conditions = _first_seen(subject_values["condition"])
    if baseline not in conditions:
        raise _missing_baseline(baseline, conditions)
    rows = []
    for (group, metric), part in subject_values.groupby(["group", "metric"], sort=False):
        samples = {
            str(c): p.set_index("subject")["value"].astype(np.float64)
            for c, p in part.groupby("condition", sort=False)
        }
        base = samples.get(baseline, pd.Series(dtype=np.float64))
        for condition in (c for c in conditions if c != baseline and c in samples):
            key = {"group": group, "metric": metric, "condition": condition}
            result = _compare(samples[condition], base, confidence, resamples, seed)
            rows.append(key | {"baseline": baseline} | result)
    table = pd.DataFrame(rows, columns=list(COMPARISON_COLUMNS))
    counts = ("n_baseline", "n_condition", "left_out")
    table = table.astype({c: np.int64 for c in counts})
    floats = [c for c in COMPARISON_COLUMNS[8:] if c != "test"]
    table[floats] = table[floats].astype(np.float64)
    table["p_adjusted"] = _adjusted(table["p_value"].to_numpy(np.float64))
    return _ordered(table, conditions, [])


def _subjects(n: int) -> str:
    return f"{n} subject" if n == 1 else f"{n} subjects"


def _sentence(condition: str, baseline: str, seen: set[str], seen_baseline: set[str]) -> str:
    """Who saw what, by the pairing rule of :func:`comparisons`."""
    both = len(seen & seen_baseline)
    start = f"{condition} vs {baseline}: "
    unpaired = f"(unpaired, between-subject: {len(seen)} and {len(seen_baseline)} subjects)"
    if both == 0:
        return start + f"no subject saw both {unpaired}"
    if both == 1:
        return start + f"only 1 subject saw both {unpaired}"
    only = len(seen ^ seen_baseline)
    if only == 0:
        return start + f"{_subjects(both)} saw both (paired, within-subject)"
    verb = "is" if only == 1 else "are"
    return (
        start + f"{_subjects(both)} saw both (paired on them); "
        f"{only} saw only one and {verb} left out of that comparison"
    )


def design(observations: pd.DataFrame, baseline: str) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """The design table (condition, subjects, sessions, events: distinct subjects, sessions
    and (session, event) pairs; baseline first, then first seen) and one sentence per other
    condition saying who saw what. Raises AnalysisError if ``baseline`` is not a condition."""
    conditions = _first_seen(observations["condition"])
    if baseline not in conditions:
        raise _missing_baseline(baseline, conditions)
    ordered = [baseline, *(c for c in conditions if c != baseline)]
    rows = []
    seen: dict[str, set[str]] = {}
    for condition in ordered:
        part = observations.loc[observations["condition"] == condition]
        seen[condition] = {str(s) for s in part["subject"]}
        events = len(part[["session", "event"]].drop_duplicates())
        rows.append((condition, len(seen[condition]), part["session"].nunique(), events))
    table = pd.DataFrame(rows, columns=["condition", "subjects", "sessions", "events"])
    table = table.astype({"subjects": np.int64, "sessions": np.int64, "events": np.int64})
    text = tuple(_sentence(c, baseline, seen[c], seen[baseline]) for c in ordered[1:])
    return table, text
