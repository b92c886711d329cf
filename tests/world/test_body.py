"""The ISO/TS 15066 body model: the table's values against the numbers of the standard's
Tables A.2 and A.3 as the issue lists them, the transient rule, and unknown regions."""

from __future__ import annotations

import pytest

from hilrig.errors import ParameterError
from hilrig.world.body import PROBE_AREA_CM2, REGIONS, SOURCE, body_region

#: region: quasi-static force N, spring constant N/mm, effective mass kg (A.2, A.3).
TABLE = {
    "skull": (130, 150, 4.4),
    "face": (65, 75, 4.4),
    "neck": (150, 50, 1.2),
    "back": (210, 35, 40),
    "chest": (140, 25, 40),
    "abdomen": (110, 10, 40),
    "pelvis": (180, 25, 40),
    "upper-arm": (150, 30, 3),
    "lower-arm": (160, 40, 2),
    "hand": (140, 75, 0.6),
    "thigh": (220, 50, 75),
    "lower-leg": (130, 60, 75),
}


def test_every_region_has_the_standard_s_force_spring_and_mass() -> None:
    assert list(REGIONS) == list(TABLE)
    for name, (force, spring, mass) in TABLE.items():
        region = body_region(name)
        assert (region.quasi_static_force_n, region.spring_constant_n_mm) == (force, spring)
        assert region.effective_mass_kg == mass
        assert region.spring_constant_n_m == 1000 * spring


def test_transient_contact_allows_twice_except_on_the_skull_and_face() -> None:
    for name, region in REGIONS.items():
        if name in ("skull", "face"):
            assert region.transient_force_n is None
        else:
            assert region.transient_force_n == 2 * region.quasi_static_force_n


def test_the_29_specific_areas_and_their_pressures() -> None:
    areas = [area for region in REGIONS.values() for area in region.areas]
    assert [a.number for a in areas] == list(range(1, 30))
    pressures = [a.quasi_static_pressure_n_cm2 for a in areas]
    assert pressures == [130, 110, 110, 140, 210, 160, 210, 120, 170, 140, 210, 190, 220, 190,
                         180, 180, 300, 270, 280, 220, 200, 260, 260, 200, 190, 250, 220, 220,
                         210]  # fmt: skip
    assert body_region("hand").quasi_static_pressure_n_cm2 == 190  # its strictest area
    assert body_region("chest").quasi_static_pressure_n_cm2 == 120


def test_the_probe_area_and_the_source_are_named() -> None:
    assert pytest.approx(1.96) == PROBE_AREA_CM2
    assert SOURCE == "ISO/TS 15066:2016, Annex A, Tables A.2 and A.3"


def test_an_unknown_region_is_refused_with_the_list() -> None:
    with pytest.raises(ParameterError) as caught:
        body_region("elbow")
    assert str(caught.value) == (
        "unknown body region 'elbow'; known: skull, face, neck, back, chest, abdomen, pelvis, "
        "upper-arm, lower-arm, hand, thigh, lower-leg"
    )
