"""The emulated joint servos: tracking within limits, watchdog hold, protective stop."""

import numpy as np

from hilrig.drivers.joint_targets.wire import Mode
from hilrig.drivers.robot_state.wire import RobotStatus
from hilrig.robot.limits import JointLimits
from hilrig.world.plant import JointServoPlant

LIMITS = JointLimits(
    position_min_rad=(-3.05,) * 6,
    position_max_rad=(3.05,) * 6,
    velocity_max_rad_s=(3.14, 3.14, 3.14, 2.6, 2.6, 2.6),
    acceleration_max_rad_s2=(10.0,) * 6,
)
MS = 1_000_000


def drive(plant: JointServoPlant, q: list[float], ticks: int, start_tick: int = 0) -> list:
    """Send q in TRACK every 1 ms tick and advance; returns the states."""
    states = []
    for n in range(start_tick, start_tick + ticks):
        plant.set_targets(np.array(q), n + 1, Mode.TRACK, n * MS)
        plant.advance(n * MS)
        states.append(plant.state(n, n * MS, (0.0,) * 6))
    return states


def test_tracks_a_target_within_velocity_and_acceleration_limits() -> None:
    plant = JointServoPlant(LIMITS)
    states = drive(plant, [2.0, -1.0, 0.5, 0.0, 0.0, 2.5], 3000)
    q = np.array([s.q_rad for s in states])
    qd = np.array([s.qd_rad_s for s in states])
    np.testing.assert_allclose(q[-1], [2.0, -1.0, 0.5, 0.0, 0.0, 2.5], atol=1e-4)
    assert (np.abs(qd) <= np.array(LIMITS.velocity_max_rad_s) + 1e-12).all()
    assert (
        np.abs(np.diff(qd, axis=0)) <= np.array(LIMITS.acceleration_max_rad_s2) * 1e-3 + 1e-12
    ).all()
    assert states[-1].status == RobotStatus.ENABLED | RobotStatus.TRACKING


def test_targets_beyond_the_position_limits_are_clamped() -> None:
    plant = JointServoPlant(LIMITS)
    states = drive(plant, [5.0, -5.0, 0.0, 0.0, 0.0, 0.0], 4000)
    assert states[-1].q_rad[0] <= 3.05 and states[-1].q_rad[1] >= -3.05
    assert abs(states[-1].q_rad[0] - 3.05) < 1e-4


def test_the_watchdog_holds_when_targets_stop() -> None:
    plant = JointServoPlant(LIMITS, watchdog_s=0.05)
    drive(plant, [1.0] * 6, 100)  # moving towards 1 rad, not there yet
    q_at_silence = plant.q_rad
    for n in range(100, 1000):  # no more writes
        plant.advance(n * MS)
    held = plant.state(0, 0, (0.0,) * 6)
    assert held.status == RobotStatus.ENABLED | RobotStatus.HOLDING
    assert plant.watchdog_trips == 1
    assert np.all(np.array(held.q_rad) < 1.0 - 0.1)  # stopped well short of the target
    assert np.all(np.array(held.q_rad) >= q_at_silence)  # after braking, not going back
    assert np.allclose(held.qd_rad_s, 0.0, atol=1e-6)


def test_a_stop_write_latches_until_cleared() -> None:
    plant = JointServoPlant(LIMITS)
    drive(plant, [0.5] * 6, 50)
    plant.set_targets(np.full(6, 3.0), 51, Mode.STOP, 50 * MS)
    for n in range(50, 800):
        plant.advance(n * MS)
    stopped = plant.state(0, 0, (0.0,) * 6)
    assert RobotStatus.PROTECTIVE_STOP in stopped.status
    assert max(stopped.q_rad) < 0.5
