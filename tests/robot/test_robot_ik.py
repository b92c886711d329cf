"""Damped-least-squares IK: round trips, warm-started tracking, limits and failure reporting."""

import numpy as np
import pytest

from hilrig.errors import ParameterError
from hilrig.robot import AUBO_I5_LIMITS, JointLimits, RobotModel


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel()


def random_configurations(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.5, 2.5, size=(count, 6))


@pytest.mark.parametrize("q_rad", random_configurations(20, seed=1))
def test_ik_round_trips_from_a_nearby_start(model: RobotModel, q_rad: np.ndarray) -> None:
    pose = model.fk(q_rad)
    start = q_rad + np.random.default_rng(2).uniform(-0.2, 0.2, size=6)
    result = model.ik(pose, start, max_iterations=50)
    assert result.converged
    assert result.position_error_m <= 1e-6 and result.rotation_error_rad <= 1e-6
    np.testing.assert_allclose(model.fk(result.q_rad), pose, atol=1e-5)


def test_warm_started_tracking_takes_at_most_two_steps_per_tick(model: RobotModel) -> None:
    q_center = np.array([0.1, -0.5, 1.2, 0.3, 1.0, 0.2])
    rates = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    q_rad = q_center.copy()
    steps = []
    for tick in range(2000):  # 2 s at 1 kHz, joints swinging 0.3 rad at up to 1.8 rad/s
        pose = model.fk(q_center + 0.3 * np.sin(rates * tick * 1e-3))
        result = model.ik(pose, q_rad, max_iterations=5)
        assert result.converged
        q_rad = result.q_rad
        steps.append(result.iterations)
    assert max(steps) <= 2


def test_start_at_the_goal_takes_no_step(model: RobotModel) -> None:
    q_rad = np.array([0.3, 0.2, -0.4, 0.1, 0.5, 0.0])
    result = model.ik(model.fk(q_rad), q_rad)
    assert result.converged and result.iterations == 0


def test_unreachable_pose_is_reported_not_converged_within_limits(model: RobotModel) -> None:
    pose = np.eye(4)
    pose[:3, 3] = [2.0, 0.0, 0.5]  # beyond the 0.886 m reach
    result = model.ik(pose, np.array([0.0, 0.5, 1.0, 0.0, 1.0, 0.0]), max_iterations=30)
    assert not result.converged
    assert result.iterations == 30
    assert result.position_error_m > 0.5
    assert AUBO_I5_LIMITS.contains(result.q_rad)


def test_iterates_are_clipped_to_the_position_limits(model: RobotModel) -> None:
    tight = JointLimits(
        position_min_rad=(-0.1,) * 6,
        position_max_rad=(0.1,) * 6,
        velocity_max_rad_s=AUBO_I5_LIMITS.velocity_max_rad_s,
        acceleration_max_rad_s2=AUBO_I5_LIMITS.acceleration_max_rad_s2,
    )
    constrained = RobotModel(limits=tight)
    goal = model.fk(np.array([1.0, 0.5, -0.5, 0.5, 0.5, 0.5]))
    result = constrained.ik(goal, np.zeros(6))
    assert not result.converged
    assert tight.contains(result.q_rad)


def test_limits_refuse_an_empty_range() -> None:
    with pytest.raises(ParameterError, match=r"joint 3: position_min_rad 1\.0 >= max 1\.0"):
        JointLimits(
            position_min_rad=(0.0, 0.0, 1.0, 0.0, 0.0, 0.0),
            position_max_rad=(1.0,) * 6,
            velocity_max_rad_s=(1.0,) * 6,
            acceleration_max_rad_s2=(1.0,) * 6,
        )
