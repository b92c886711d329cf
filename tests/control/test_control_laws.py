"""The laws' damping and stiffness against hand-computed values (docs/control.md)."""

import math

import numpy as np
import pytest

from hilrig.control import combine, gains, preset

EE = "paper-end-effector"  # m=20, b_d=150, k_d=300, a1=20, a2=0.7, beta=30, delta=0.2


@pytest.mark.parametrize(
    ("law", "f", "b", "k"),
    [
        ("fixed", 5.0, 150.0, 300.0),
        ("variable-stiffness", 5.0, 150.0, 300.0 * (1 - 0.7 * math.tanh(25.0))),
        ("variable-stiffness", 0.5, 150.0, 300.0 * (1 - 0.7 * math.tanh(0.25))),
        # above delta: reduction a1*|f| = 10 < beta
        ("adaptive", 0.5, 140.0, 300.0 * (1 - 0.7 * math.tanh(0.25))),
        # reduction 100 capped at beta = 30
        ("adaptive", -5.0, 120.0, 300.0 * (1 - 0.7 * math.tanh(25.0))),
        # at or below delta the damping stays b_d (stiffness still follows chi)
        ("adaptive", 0.2, 150.0, 300.0 * (1 - 0.7 * math.tanh(0.04))),
        ("adaptive", 0.0, 150.0, 300.0),
    ],
)
def test_gains_match_hand_computation(law: str, f: float, b: float, k: float) -> None:
    b_out, k_out = gains(law, [[f]], EE)
    assert b_out[0, 0] == pytest.approx(b, rel=1e-15)
    assert k_out[0, 0] == pytest.approx(k, rel=1e-15)


def test_chi_abs_reading() -> None:
    _, k = gains("adaptive", [[0.5]], {"preset": EE, "chi": "abs"})
    assert k[0, 0] == pytest.approx(300.0 * (1 - 0.7 * math.tanh(0.5)), rel=1e-15)


def test_chi_group_square_reading_uses_the_whole_group() -> None:
    _, k = gains("adaptive", [[0.3, 0.4, 0.0]], {"preset": EE, "chi": "group-square"})
    expected = 300.0 * (1 - 0.7 * math.tanh(0.25))  # |f|^2 = 0.09 + 0.16
    np.testing.assert_allclose(k[0], [expected] * 3, rtol=1e-15)


def test_chi_group_square_keeps_groups_apart() -> None:
    params = combine((preset(EE), 2), (preset(EE), 1)).with_(chi="group-square")
    _, k = gains("adaptive", [[1.0, 0.0, 0.0]], params)
    assert k[0, 1] == pytest.approx(300.0 * (1 - 0.7 * math.tanh(1.0)), rel=1e-15)
    assert k[0, 2] == 300.0


def test_beta_max_reading_as_printed_floors_at_b_min() -> None:
    params = {"preset": EE, "beta_reading": "max", "b_min": 40.0}
    b, _ = gains("adaptive", [[0.0], [0.5], [2.0], [10.0]], params)
    # reduction = max(a1*|f| above delta else 0, beta): 30, 30, 40, 200 -> floored at 40
    np.testing.assert_allclose(b[:, 0], [120.0, 120.0, 110.0, 40.0], rtol=1e-15)


def test_beta_max_reading_default_floor_is_a_tenth_of_b_d() -> None:
    b, _ = gains("adaptive", [[100.0]], {"preset": EE, "beta_reading": "max"})
    assert b[0, 0] == pytest.approx(15.0)


def test_gains_are_vectorised_with_per_axis_parameters() -> None:
    params = combine((preset(EE), 1), (preset("paper-joint"), 1))
    b, k = gains("adaptive", [[5.0, 5.0]], params)
    assert b[0].tolist() == [120.0, 30.0]
    np.testing.assert_allclose(k[0], np.array([300.0, 150.0]) * (1 - 0.7 * math.tanh(25.0)))


def test_saturated_chi_equals_libm_tanh() -> None:
    # The kernel skips tanh where it rounds to 1.0; the stiffness must be what tanh gives.
    forces = np.linspace(4.0, 8.0, 4001)[:, None]
    _, k = gains("variable-stiffness", forces, EE)
    expected = [300.0 * (1 - 0.7 * math.tanh(f * f)) for f in forces[:, 0]]
    assert k[:, 0].tolist() == expected
