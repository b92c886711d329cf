"""A realistic synthetic :class:`StudyReport` for the report's tests: 6 subjects, the fixed law
(baseline) and the adaptive law, an end-effector and a body scenario each (Cartesian and joint
groups), one excluded session, quality flags, and one representative event per condition and
group (2000 samples)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
from scipy import stats

from hilrig.study.records import (
    COMPARISON_COLUMNS,
    DISTRIBUTION_COLUMNS,
    OBSERVATION_COLUMNS,
    STUDY_METRICS,
    SUBJECT_COLUMNS,
    EventCurve,
    StudyReport,
)

SUBJECTS = tuple(f"S{i:02d}" for i in range(1, 7))
CONDITIONS = ("fixed", "adaptive")
BASELINE = "fixed"
SCENARIOS = {"end_effector": "cartesian", "body": "joint"}
EXCLUDED_SESSION = "20261120-S06-fixed-end_effector"
EXCLUDED_REASON = "force/torque sensor saturated during event 1"
EVENTS_PER_SESSION = 3
CURVE_SAMPLES = 2000
# (group, metric) -> typical value under (fixed, adaptive)
TYPICAL = {
    "cartesian": {
        "peak_force": (82.0, 61.0),
        "impulse": (6.1, 5.2),
        "max_abs_offset": (0.021, 0.048),
        "time_to_max_offset_s": (0.24, 0.41),
        "recovery_time_s": (1.15, 1.8),
        "tracking_rms": (0.0008, 0.0011),
        "margin_pct": (34.0, 51.0),
    },
    "joint": {
        "peak_force": (24.0, 17.5),
        "impulse": (2.2, 1.9),
        "max_abs_offset": (0.031, 0.083),
        "time_to_max_offset_s": (0.3, 0.47),
        "recovery_time_s": (1.4, 2.1),
        "tracking_rms": (0.0009, 0.0013),
        "margin_pct": (41.0, 58.0),
    },
}


def session_id(subject: str, condition: str, scenario: str) -> str:
    return f"20261120-{subject}-{condition}-{scenario}"


def _catalogue() -> pd.DataFrame:
    rows = []
    for number, (subject, condition, scenario) in enumerate(
        (s, c, sc) for s in SUBJECTS for c in CONDITIONS for sc in SCENARIOS
    ):
        session = session_id(subject, condition, scenario)
        flags = "dropped_ticks" if number % 7 == 3 else ""
        if session == EXCLUDED_SESSION:
            flags = "force_saturated,late_start"
        params = {"m": 2.0, "b_d": 120.0, "k_d": 600.0}
        rows.append(
            {
                "session": session,
                "subject": subject,
                "controller": condition,
                "condition": condition,
                "params": json.dumps(params),
                "scenario": scenario,
                "settings": json.dumps({"rate_hz": 500, "events": EVENTS_PER_SESSION}),
                "body_region": "hand" if scenario == "end_effector" else "forearm",
                "start_utc": f"2026-11-20T{9 + number // 4:02d}:{(number % 4) * 15:02d}:00Z",
                "duration_s": 95.0 + 3.7 * number,
                "collisions": EVENTS_PER_SESSION,
                "faults": 0,
                "ticks": 47500 + 1850 * number,
                "dropped": 4 if flags else 0,
                "hold_ticks": 0,
                "missed_pct": 0.008 if flags else 0.0,
                "complete": True,
                "ended_cleanly": session != EXCLUDED_SESSION,
                "flags": flags,
                "excluded": EXCLUDED_REASON if session == EXCLUDED_SESSION else "",
                "path": f"sessions/{session}.mcap",
                "parts": 1,
                "size_bytes": 18_000_000 + 250_000 * number,
            }
        )
    return pd.DataFrame(rows)


def _observations(rng: np.random.Generator) -> pd.DataFrame:
    rows = []
    for subject_index, subject in enumerate(SUBJECTS):
        for condition_index, condition in enumerate(CONDITIONS):
            for scenario, group in SCENARIOS.items():
                session = session_id(subject, condition, scenario)
                if session == EXCLUDED_SESSION:
                    continue
                axis = "z" if group == "cartesian" else "joint2"
                for metric in STUDY_METRICS:
                    typical = TYPICAL[group][metric][condition_index]
                    subject_factor = 1.0 + 0.08 * (subject_index - 2.5) / 2.5
                    events = [0] if metric == "tracking_rms" else range(EVENTS_PER_SESSION)
                    for event in events:
                        value = typical * subject_factor * rng.lognormal(0.0, 0.07)
                        if metric == "recovery_time_s" and subject == "S03" and event == 2:
                            value = math.nan  # never recovered within its window
                        rows.append((session, subject, condition, event, group, axis, metric,
                                     value))  # fmt: skip
    return pd.DataFrame(rows, columns=list(OBSERVATION_COLUMNS))


def _distributions(values: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (group, metric, condition), frame in values.groupby(
        ["group", "metric", "condition"], sort=False
    ):
        v = frame["value"].dropna()
        rows.append(
            (group, metric, condition, len(v), int(frame["events"].sum()), v.median(),
             v.quantile(0.25), v.quantile(0.75), v.mean(), v.std(ddof=1), v.min(), v.max())
        )  # fmt: skip
    return pd.DataFrame(rows, columns=list(DISTRIBUTION_COLUMNS))


def _comparisons(values: pd.DataFrame, rng: np.random.Generator) -> pd.DataFrame:
    rows = []
    for (group, metric), frame in values.groupby(["group", "metric"], sort=False):
        wide = frame.pivot(index="subject", columns="condition", values="value")
        for condition in CONDITIONS[1:]:
            both = wide[[BASELINE, condition]].dropna()
            n_baseline = int(wide[BASELINE].notna().sum())
            left_out = n_baseline + int(wide[condition].notna().sum()) - 2 * len(both)
            diff = (both[condition] - both[BASELINE]).to_numpy()
            test = stats.wilcoxon(diff)
            boot = [np.median(rng.choice(diff, len(diff))) for _ in range(500)]
            positive = float((diff > 0).sum())
            effect = (2.0 * positive - len(diff)) / len(diff)
            rows.append(
                [group, metric, condition, BASELINE, "paired", len(both), len(both), left_out,
                 both[BASELINE].median(), both[condition].median(), float(np.median(diff)),
                 float(np.quantile(boot, 0.025)), float(np.quantile(boot, 0.975)), "wilcoxon",
                 float(test.statistic), float(test.pvalue), math.nan, effect]
            )  # fmt: skip
    frame = pd.DataFrame(rows, columns=list(COMPARISON_COLUMNS))
    p = frame["p_value"].to_numpy()
    order = np.argsort(p)
    adjusted = p[order] * len(p) / np.arange(1, len(p) + 1)
    adjusted = np.minimum.accumulate(adjusted[::-1])[::-1].clip(max=1.0)
    frame.loc[frame.index[order], "p_adjusted"] = adjusted
    return frame


def event_curve(condition: str, group: str, subject: str = "S02") -> EventCurve:
    """A collision of 0.15 s and its recovery, as the adaptive or the fixed law answers it."""
    t = np.linspace(-0.2, 2.8, CURVE_SAMPLES)
    adaptive = condition == "adaptive"
    scale = 1.0 if group == "cartesian" else 0.3
    pulse = np.where((t >= 0) & (t <= 0.15), np.sin(np.pi * np.clip(t, 0, 0.15) / 0.15), 0.0)
    force = scale * (62.0 if adaptive else 80.0) * pulse
    b0, k0 = 120.0 * scale, 600.0 * scale
    active = np.exp(-np.clip(t, 0.0, None) / 0.35) * (t >= 0)
    damping = b0 * (1.0 - 0.6 * active) if adaptive else np.full_like(t, b0)
    stiffness = k0 * (1.0 - 0.8 * active) if adaptive else np.full_like(t, k0)
    zeta = damping / (2.0 * np.sqrt(2.0 * stiffness))
    peak = (0.048 if adaptive else 0.021) * (1.6 if group == "joint" else 1.0)
    tau = 0.45 if adaptive else 0.3
    shape = np.clip(t, 0.0, None) / tau * np.exp(1.0 - np.clip(t, 0.0, None) / tau)
    session = session_id(subject, condition, "end_effector" if group == "cartesian" else "body")
    return EventCurve(
        condition=condition, subject=subject, session=session, event=1, group=group,
        axis="z" if group == "cartesian" else "joint2", t_s=t, force=force,
        offset=peak * shape, damping=damping, stiffness=stiffness, zeta=zeta,
    )  # fmt: skip


def study_report(*, exclusion_reason: str = EXCLUDED_REASON) -> StudyReport:
    """The fixture report (deterministic)."""
    rng = np.random.default_rng(2026)
    catalogue = _catalogue()
    catalogue.loc[catalogue["excluded"] != "", "excluded"] = exclusion_reason
    observations = _observations(rng)
    values = (
        observations.groupby(["subject", "condition", "group", "metric"], sort=False)["value"]
        .agg(value="mean", events="count")
        .reset_index()[list(SUBJECT_COLUMNS)]
    )
    kept = catalogue[catalogue["excluded"] == ""]
    design = pd.DataFrame(
        {
            "condition": list(CONDITIONS),
            "subjects": [kept[kept["condition"] == c]["subject"].nunique() for c in CONDITIONS],
            "sessions": [int((kept["condition"] == c).sum()) for c in CONDITIONS],
            "events": [int(kept[kept["condition"] == c]["collisions"].sum()) for c in CONDITIONS],
        }
    )
    exclusions = pd.DataFrame(
        {"target": [EXCLUDED_SESSION], "reason": [exclusion_reason],
         "removed": [f"1 session, {EVENTS_PER_SESSION} events"]}
    )  # fmt: skip
    return StudyReport(
        name="Adaptive admittance, hand and forearm",
        created_utc="2026-12-02T17:45:00Z",
        software_version="0.1.0",
        command="hilrig report studies/hand-forearm -o report.html",
        baseline=BASELINE,
        catalogue=catalogue,
        exclusions=exclusions,
        design=design,
        design_text=(
            "6 subjects saw both conditions (paired comparisons).",
            "S06 saw only adaptive on the end effector after the exclusion; "
            "left out of the paired Cartesian comparisons.",
        ),
        observations=observations,
        subject_values=values,
        distributions=_distributions(values),
        comparisons=_comparisons(values, rng),
        curves=tuple(event_curve(c, g) for g in ("cartesian", "joint") for c in CONDITIONS),
        notes=(
            "3 sessions dropped ticks (at most 0.008 % missed).",
            "S03: one event never recovered within its window (recovery time missing).",
        ),
    )


def expected_figures(report: StudyReport) -> int:
    """Distribution figures (one per group and metric with values) plus two per group with
    curves."""
    values = report.subject_values.dropna(subset=["value"])
    groups = {c.group for c in report.curves}
    return int(values.groupby(["group", "metric"]).ngroups) + 2 * len(groups)
