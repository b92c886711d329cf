"""Scenario settings: every field settable from text or TOML values, bad ones refused in one
line naming the scenario, the setting and the value; the values round-trip."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.errors import ParameterError
from hilrig.world.scenarios import (
    SCENARIOS,
    HandContact,
    scenario,
    settings_fields,
    settings_of,
)


def test_text_and_toml_values_set_every_kind_of_field() -> None:
    from_text = scenario(
        "hand-contact",
        {"stiffness_n_m": "800", "direction_in_base": "1, 0, 0", "period_s": "none"},
    )
    from_toml = scenario(
        "hand-contact", {"stiffness_n_m": 800, "direction_in_base": [1, 0, 0], "period_s": None}
    )
    for volunteer in (from_text, from_toml):
        assert isinstance(volunteer, HandContact)
        assert volunteer.stiffness_n_m == 800.0
        assert volunteer.direction_in_base == (1.0, 0.0, 0.0)
        assert volunteer.period_s is None
        assert volunteer.depth_m == HandContact().depth_m  # the rest keep their defaults
    assert scenario("paper-body", {"period_s": "12"}).period_s == 12.0  # type: ignore[attr-defined]


def test_every_field_but_the_name_is_a_setting() -> None:
    assert [f.name for f in settings_fields("hand-contact")] == [
        "direction_in_base",
        "start_s",
        "gap_m",
        "depth_m",
        "speed_m_s",
        "hold_s",
        "stiffness_n_m",
        "damping_n_s_m",
        "contact_point_in_sensor",
        "period_s",
    ]
    assert [f.name for f in settings_fields("none")] == []
    for name in SCENARIOS:
        assert all(f.metadata.get("doc") for f in settings_fields(name)), name


@pytest.mark.parametrize(
    ("name", "values", "message"),
    [
        ("walk", {}, "unknown scenario 'walk'; known: hand-contact, none, paper-body, "
         "paper-end-effector"),
        ("hand-contact", {"stifness_n_m": "1"}, "scenario hand-contact: no setting "
         "'stifness_n_m'; its settings: direction_in_base, start_s, gap_m, depth_m, speed_m_s, "
         "hold_s, stiffness_n_m, damping_n_s_m, contact_point_in_sensor, period_s"),
        ("none", {"period_s": "1"}, "scenario none: no setting 'period_s'; its settings: none"),
        ("hand-contact", {"stiffness_n_m": "soft"},
         "scenario hand-contact: stiffness_n_m 'soft' is not a number"),
        ("hand-contact", {"stiffness_n_m": "nan"},
         "scenario hand-contact: stiffness_n_m 'nan' is not a finite number"),
        ("hand-contact", {"stiffness_n_m": "-5"},
         "scenario hand-contact: stiffness_n_m -5 must be >= 0"),
        ("hand-contact", {"speed_m_s": "0"}, "scenario hand-contact: speed_m_s 0 must be > 0"),
        ("hand-contact", {"direction_in_base": "1,0"},
         "scenario hand-contact: direction_in_base '1,0' is not three numbers x,y,z"),
        ("hand-contact", {"direction_in_base": "0,0,0"},
         "scenario hand-contact: direction_in_base (0, 0, 0) has no direction"),
        ("hand-contact", {"period_s": "3"}, "scenario hand-contact: period_s 3 is shorter than "
         "its collision (4.6 s from the period's start)"),
        ("paper-end-effector", {"period_s": "5"}, "scenario paper-end-effector: period_s 5 is "
         "shorter than its collision (6 s from the period's start)"),
    ],
)  # fmt: skip
def test_bad_settings_are_refused_in_one_line(
    name: str, values: dict[str, object], message: str
) -> None:
    with pytest.raises(ParameterError) as caught:
        scenario(name, values)
    assert str(caught.value) == message


finite = st.floats(0.001, 1e4, allow_nan=False)
vector = st.tuples(finite, finite, finite)


@settings(max_examples=100, deadline=None)
@given(
    st.fixed_dictionaries(
        {
            "direction_in_base": vector,
            "stiffness_n_m": finite,
            "damping_n_s_m": finite,
            "depth_m": finite,
            "speed_m_s": finite,
            "contact_point_in_sensor": vector,
        }
    )
)
def test_recorded_settings_rebuild_the_same_volunteer(values: dict[str, object]) -> None:
    volunteer = scenario("hand-contact", {**values, "period_s": None})
    recorded = settings_of(volunteer)
    again = scenario("hand-contact", recorded)
    assert settings_of(again) == recorded
    assert recorded["stiffness_n_m"] == values["stiffness_n_m"]
    assert recorded["direction_in_base"] == list(values["direction_in_base"])  # type: ignore[arg-type]


def test_the_settings_change_what_the_volunteer_does() -> None:
    # twice the stiffness, twice the force at the same penetration (damping off, tool still)
    pose = __import__("numpy").eye(4)
    soft, stiff = (
        scenario("hand-contact", {"stiffness_n_m": k, "damping_n_s_m": 0, "period_s": "none"})
        for k in ("300", "600")
    )
    t_s = 2.0 + (0.05 + 0.02) / 0.1  # 2 cm past the tool's start
    f_soft, f_stiff = (math.hypot(*v.wrench_in_sensor(t_s, pose)[:3]) for v in (soft, stiff))
    assert f_soft == pytest.approx(300 * 0.02)
    assert f_stiff == pytest.approx(2 * f_soft)
