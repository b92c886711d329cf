"""Safety verdicts on hand-computed collisions: every quantity by its formula (docs/safety.md),
the 300 N transient on a hand that is over, no transient contact on the skull, and hypothesis:
the verdict never improves with more force or a smaller contact area."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.analysis.events import AxisGroup, CollisionEvent
from hilrig.analysis.sources import Run
from hilrig.analysis.verdict import VerdictConfig, judge
from hilrig.errors import AnalysisError
from hilrig.robot import RobotModel
from hilrig.world.body import body_region

MODEL = RobotModel()
HOME = np.array([0.0, -0.3, 1.6, 0.3, np.pi / 2, 0.0])
T = np.arange(0.0, 2.0, 0.001)
EVENT = CollisionEvent(AxisGroup.CARTESIAN, 0.5, 1.51, 0.0)


def collision(transient_n: float, after_n: float, *, moving_m_s: float = 0.0) -> Run:
    """A push along +y: ``transient_n`` at 0.6 s, then ``after_n`` held from 1.1 s to 1.5 s;
    the commanded TCP moving along -y (towards the body) at ``moving_m_s`` until the onset."""
    magnitude = np.interp(T, [0.5, 0.6, 0.7, 1.1, 1.5, 1.51], [0, transient_n, 0, after_n,
                                                                  after_n, 0])  # fmt: skip
    force = np.zeros((len(T), 9))
    force[:, 1] = magnitude
    joints = np.tile(HOME, (len(T), 1))
    if moving_m_s:
        jac = MODEL.jacobian(HOME)[:3]
        rate = np.linalg.lstsq(jac, np.array([0.0, -moving_m_s, 0.0]), rcond=None)[0]
        joints += np.outer(np.minimum(T, 0.5) - 0.5, rate)
    axes = ("x", "y", "z", *(f"joint{j}" for j in range(1, 7)))
    zeros = np.zeros_like(force)
    return Run("fixed", "fixed", axes, T, force, zeros, zeros, T, joints)


def verdict_of(run: Run, region: str = "hand", area_cm2: float = 1.96) -> object:
    (v,) = judge(run, [EVENT], body_region(region), area_cm2, 0.5, MODEL)
    return v


def test_every_quantity_by_its_formula() -> None:
    v = verdict_of(collision(100.0, 40.0))
    mass = MODEL.effective_mass_kg(HOME, np.array([0.0, 1.0, 0.0]))
    reduced = 1 / (1 / mass + 1 / 0.6)
    assert (v.peak_force_n, v.transient_peak_n, v.quasi_static_peak_n) == (100.0, 100.0, 40.0)
    assert (v.transient_limit_n, v.quasi_static_limit_n) == (280.0, 140.0)
    assert v.pressure_n_cm2 == pytest.approx(100.0 / 1.96)
    assert (v.transient_pressure_limit_n_cm2, v.quasi_static_pressure_limit_n_cm2) == (380, 190)
    assert v.energy_j == pytest.approx(100.0**2 / (2 * 75_000.0))
    assert v.effective_mass_kg == pytest.approx(mass)
    assert v.reduced_mass_kg == pytest.approx(reduced)
    assert v.speed_limit_m_s == pytest.approx(280.0 / math.sqrt(reduced * 75_000.0))
    assert v.approach_speed_m_s == pytest.approx(0.0, abs=1e-12)
    margins = {
        "transient force": 100 * (280 - 100) / 280,
        "quasi-static force": 100 * (140 - 40) / 140,
        "transient pressure": 100 * (380 - 100 / 1.96) / 380,
        "quasi-static pressure": 100 * (190 - 40 / 1.96) / 190,
        "approach speed": 100.0,
    }
    assert v.binding == "transient force"
    assert v.margin_pct == pytest.approx(min(margins.values()))
    assert v.verdict == "within"


def test_the_approach_speed_is_the_tcp_s_towards_the_body() -> None:
    v = verdict_of(collision(100.0, 50.0, moving_m_s=0.25))
    assert v.approach_speed_m_s == pytest.approx(0.25, rel=1e-3)


def test_a_300_n_transient_peak_on_a_hand_is_over() -> None:
    v = verdict_of(collision(300.0, 20.0))
    assert v.verdict == "over" and v.binding == "transient force"
    assert v.margin_pct == pytest.approx(100 * (280 - 300) / 280)


def test_no_transient_contact_is_permitted_on_the_skull() -> None:
    v = verdict_of(collision(5.0, 2.0), region="skull")
    assert math.isnan(v.transient_limit_n) and math.isnan(v.speed_limit_m_s)
    assert (v.verdict, v.binding, v.margin_pct) == (
        "over", "transient contact (not permitted)", -100.0)  # fmt: skip


@settings(max_examples=40, deadline=None)
@given(
    st.floats(1.0, 500.0), st.floats(1.0, 300.0), st.floats(1.01, 3.0), st.floats(0.2, 20.0),
    st.sampled_from(["hand", "chest", "lower-leg", "neck"]),
)  # fmt: skip
def test_more_force_or_less_area_never_improves_the_verdict(
    transient: float, after: float, factor: float, area: float, region: str
) -> None:
    base = verdict_of(collision(transient, after), region, area)
    harder = verdict_of(collision(transient * factor, after * factor), region, area)
    smaller = verdict_of(collision(transient, after), region, area / factor)
    for worse in (harder, smaller):
        assert worse.margin_pct <= base.margin_pct + 1e-9
        assert not (base.verdict == "over" and worse.verdict == "within")


@pytest.mark.parametrize(
    ("config", "message"),
    [
        (dict(body_region="elbow"), "--body-region: unknown body region 'elbow'; known: skull, "
         "face, neck, back, chest, abdomen, pelvis, upper-arm, lower-arm, hand, thigh, lower-leg"),
        (dict(contact_area_cm2=0.0), "--contact-area-cm2 0: must be a finite area > 0"),
        (dict(transient_s=-1.0), "--transient-s -1: must be a time > 0 s"),
    ],
)  # fmt: skip
def test_bad_settings_are_refused_in_one_line(config: dict, message: str) -> None:
    with pytest.raises(AnalysisError) as caught:
        VerdictConfig(**config)
    assert str(caught.value) == message
