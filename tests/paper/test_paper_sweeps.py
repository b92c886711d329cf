"""Section 2.1 sweeps: step-response metrics against closed forms of m e'' + b e' + k e = f."""

import math

import pytest
from scipy.optimize import brentq

from hilrig.paper.experiments import (
    EXPERIMENT_3_DAMPING_N_S_PER_M,
    SWEEP_FORCE_N,
    SWEEPS,
    StepMetrics,
    SweepRun,
    SweptParameter,
    run_sweep,
)


@pytest.fixture(scope="module")
def sweeps() -> tuple[SweepRun, ...]:
    return tuple(run_sweep(sweep) for sweep in SWEEPS)


@pytest.fixture(scope="module")
def metrics(sweeps: tuple[SweepRun, ...]) -> list[StepMetrics]:
    return [m for run in sweeps for m in run.metrics]


def test_sweeps_are_the_papers_cases() -> None:
    cases = {s.parameter: [s.params(v) for v in s.values] for s in SWEEPS}
    assert [c["m"] for c in cases[SweptParameter.MASS]] == [1, 10, 20, 30, 40]
    assert {(c["b_d"], c["k_d"]) for c in cases[SweptParameter.MASS]} == {(150, 300)}
    assert [c["b_d"] for c in cases[SweptParameter.DAMPING]] == [50, 100, 150, 200, 250]
    assert {(c["m"], c["k_d"]) for c in cases[SweptParameter.DAMPING]} == {(20, 300)}
    assert [c["k_d"] for c in cases[SweptParameter.STIFFNESS]] == [100, 200, 300, 400, 500]
    assert {(c["m"], c["b_d"]) for c in cases[SweptParameter.STIFFNESS]} == {(20, 150)}
    assert EXPERIMENT_3_DAMPING_N_S_PER_M == 150.0


def test_steady_state_is_f_over_k(metrics: list[StepMetrics]) -> None:
    for case in metrics:
        assert case.steady_state_m == pytest.approx(SWEEP_FORCE_N / case.k_n_per_m, rel=1e-5)


def test_underdamped_overshoot_and_peak_time_match_closed_form(metrics: list[StepMetrics]) -> None:
    underdamped = [case for case in metrics if case.zeta < 1.0]
    assert len(underdamped) >= 5
    for case in underdamped:
        root = math.sqrt(1.0 - case.zeta**2)
        assert case.overshoot_pct == pytest.approx(
            100.0 * math.exp(-case.zeta * math.pi / root), rel=1e-3
        )
        omega_d = math.sqrt(case.k_n_per_m / case.m_kg) * root
        assert case.time_to_peak_s == pytest.approx(math.pi / omega_d, abs=0.002)


def test_overdamped_response_has_no_overshoot_or_peak_time(metrics: list[StepMetrics]) -> None:
    overdamped = [case for case in metrics if case.zeta > 1.0]
    assert len(overdamped) >= 5
    for case in overdamped:
        assert case.overshoot_pct == 0.0
        assert case.time_to_peak_s is None
        assert case.peak_offset_m <= case.static_offset_m * (1 + 1e-9)


def _overdamped_step(case: StepMetrics, t_s: float) -> float:
    """Closed-form e(t) of an overdamped m e'' + b e' + k e = f from rest, m."""
    m, b, k = case.m_kg, case.b_n_s_per_m, case.k_n_per_m
    disc = math.sqrt(b * b - 4.0 * m * k)
    r1, r2 = (-b + disc) / (2.0 * m), (-b - disc) / (2.0 * m)
    growth = (r2 * math.exp(r1 * t_s) - r1 * math.exp(r2 * t_s)) / (r1 - r2)
    return case.static_offset_m * (1.0 + growth)


def _below_98_percent(t_s: float, case: StepMetrics) -> float:
    return _overdamped_step(case, t_s) - 0.98 * case.static_offset_m


def test_overdamped_settling_time_is_the_closed_form_crossing_of_98_percent(
    metrics: list[StepMetrics],
) -> None:
    for case in (c for c in metrics if c.zeta > 1.0):
        crossing_s = brentq(_below_98_percent, 1e-6, 20.0, args=(case,))
        assert case.settling_time_s == pytest.approx(crossing_s, abs=0.0021)


def test_section_2_1_trends_hold(sweeps: tuple[SweepRun, ...]) -> None:
    mass, damping, stiffness = (run.metrics for run in sweeps)
    # larger m: more overshoot; smaller b: faster and, when too small, overshoot
    assert [c.overshoot_pct for c in mass] == sorted(c.overshoot_pct for c in mass)
    assert mass[0].overshoot_pct == 0.0 < mass[-1].overshoot_pct
    speeds = [c.peak_speed_m_per_s for c in damping]
    assert speeds == sorted(speeds, reverse=True)
    assert damping[0].overshoot_pct > 30.0
    # larger k: smaller displacement
    offsets = [c.peak_offset_m for c in stiffness]
    assert offsets == sorted(offsets, reverse=True)
