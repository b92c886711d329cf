"""The paper's force/torque profiles (eq. 15-19) against hand-computed values."""

import numpy as np
import pytest

from hilrig.paper import (
    BODY_PROFILES,
    END_EFFECTOR_PROFILES,
    Profile,
    end_effector_force,
    fx,
    fy,
    fz,
    joint_torque,
    tau1,
    tau2,
)

ALL_PROFILES = (*END_EFFECTOR_PROFILES, *BODY_PROFILES)


@pytest.mark.parametrize(
    ("profile", "t_s", "expected"),
    [
        (fx, 4.0, 0.0),
        (fx, 4.5, -2.5),
        (fx, 5.0, -5.0),
        (fx, 5.5, -2.5),
        (fx, 6.0, 0.0),
        (fy, 4.15, 1.75),
        (fy, 4.3, 3.5),
        (fy, 5.0, 3.5),
        (fy, 5.6, 3.5),
        (fy, 5.8, 1.75),
        (fy, 6.0, 0.0),
        (fz, 4.25, -0.75),
        (fz, 4.5, -1.5),
        (fz, 4.85, -2.0),
        (fz, 5.2, -2.5),
        (fz, 5.6, -1.25),
        (fz, 6.0, 0.0),
        (tau1, 3.75, 2.5),
        (tau1, 4.0, 5.0),
        (tau1, 4.5, 5.0),
        (tau1, 5.25, 2.5),
        (tau1, 5.5, 0.0),
        (tau2, 3.75, 2.5),
        (tau2, 4.5, 5.0),
    ],
)
def test_profile_matches_hand_computed_value(profile: Profile, t_s: float, expected: float) -> None:
    assert float(profile(t_s)) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("profile", ALL_PROFILES, ids=lambda p: p.name)
def test_profile_is_zero_outside_its_support(profile: Profile) -> None:
    start_s, stop_s = profile.breakpoints_s[0], profile.breakpoints_s[-1]
    outside = np.array([0.0, 1.0, start_s - 1e-6, stop_s + 1e-6, 10.0, 20.0])
    np.testing.assert_array_equal(profile(outside), 0.0)
    assert np.abs(profile(np.linspace(start_s + 1e-6, stop_s - 1e-6, 101))).min() > 0.0


@pytest.mark.parametrize("profile", ALL_PROFILES, ids=lambda p: p.name)
def test_profile_is_continuous_at_every_breakpoint(profile: Profile) -> None:
    # Breakpoints include the support's ends, where the profile must meet zero.
    eps_s = 1e-9
    for t_s in profile.breakpoints_s:
        left, at, right = profile(np.array([t_s - eps_s, t_s, t_s + eps_s]))
        assert left == pytest.approx(at, abs=1e-7), f"{profile.name} jumps at {t_s} s"
        assert right == pytest.approx(at, abs=1e-7), f"{profile.name} jumps at {t_s} s"


def test_profile_evaluates_arrays_elementwise() -> None:
    t_s = np.array([[4.5, 5.0], [5.5, 7.0]])
    np.testing.assert_allclose(fx(t_s), [[-2.5, -5.0], [-2.5, 0.0]], atol=1e-12)


def test_end_effector_force_stacks_fx_fy_fz() -> None:
    t_s = np.arange(0.0, 8.0, 0.01)
    force = end_effector_force(t_s)
    assert force.shape == (t_s.size, 3)
    for column, profile in enumerate((fx, fy, fz)):
        np.testing.assert_array_equal(force[:, column], profile(t_s))


def test_joint_torque_drives_joints_1_and_2_only() -> None:
    t_s = np.arange(0.0, 8.0, 0.01)
    torque = joint_torque(t_s)
    assert torque.shape == (t_s.size, 6)
    np.testing.assert_array_equal(torque[:, 0], tau1(t_s))
    np.testing.assert_array_equal(torque[:, 1], tau1(t_s))
    np.testing.assert_array_equal(torque[:, 2:], 0.0)
    assert torque[:, 0].max() == pytest.approx(5.0)
