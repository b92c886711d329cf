"""Whatever force and torque reach the loop, the joint targets it commands stay in the limits.

The thing under test is the tick (controller, IK, safety clamp), driven tick by tick on
synthetic time. The three devices are minimal in-process stand-ins: the drivers themselves are
tested through their real transports elsewhere, and no transport can carry arbitrary adversarial
input at this rate.
"""

from collections.abc import Sequence

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.drivers.emulated.rig import HOME_Q_RAD
from hilrig.drivers.ft_sensor import FtSample
from hilrig.drivers.gravity import GravityCompensator
from hilrig.drivers.joint_targets import WriterStats
from hilrig.drivers.joint_targets_map import Mode
from hilrig.drivers.robot_state import ReceivedState
from hilrig.drivers.robot_state_codec import RobotState, RobotStatus
from hilrig.rig import (
    ControlLoop,
    DeadlineTimer,
    LoopConfig,
    SafetyClamp,
    SafetyConfig,
    make_trajectory,
)
from hilrig.robot import RobotModel

PERIOD_NS = 1_000_000
MODEL = RobotModel()


class Sensor:
    def __init__(self) -> None:
        self.sample: FtSample | None = None

    def latest(self) -> FtSample | None:
        return self.sample

    def drain(self) -> list[FtSample]:
        return []


class Robot:
    def __init__(self) -> None:
        self.received: ReceivedState | None = None

    def latest(self) -> ReceivedState | None:
        return self.received

    def drain(self) -> list[ReceivedState]:
        return []


class Targets:
    def __init__(self) -> None:
        self.sent: list[np.ndarray] = []
        self.errors = 0
        self.last_error = None
        self.stats = WriterStats()

    def write(self, value: np.ndarray, mode: Mode = Mode.TRACK, *, source_ns: int = 0) -> None:
        self.sent.append(np.array(value))


values = st.floats(allow_nan=True, allow_infinity=True, width=64) | st.floats(-500, 500)


@settings(max_examples=40, deadline=None)
@given(inputs=st.lists(st.tuples(*[values] * 12), min_size=1, max_size=300))
def test_commanded_targets_stay_inside_the_limits_whatever_the_input(
    inputs: Sequence[tuple[float, ...]],
) -> None:
    sensor, robot, targets = Sensor(), Robot(), Targets()
    q0 = np.asarray(HOME_Q_RAD)
    safety_config = SafetyConfig()
    loop = ControlLoop(
        LoopConfig(),
        sensor=sensor,  # type: ignore[arg-type]
        robot=robot,  # type: ignore[arg-type]
        targets=targets,  # type: ignore[arg-type]
        compensator=GravityCompensator(),
        trajectory=make_trajectory("circle", MODEL.fk(q0)),
        safety=SafetyClamp(safety_config, MODEL, q0),
        model=MODEL,
    )
    q = q0.copy()
    robot.received = ReceivedState(
        0, RobotState(0, 0, tuple(q), (0.0,) * 6, (0.0,) * 6, RobotStatus(1))
    )
    timer = DeadlineTimer(PERIOD_NS)
    for n, values_ in enumerate(inputs):
        now = (n + 1) * PERIOD_NS
        wrench, torque = values_[:6], values_[6:]
        sensor.sample = FtSample(now, n, wrench)  # type: ignore[arg-type]
        robot.received = ReceivedState(
            now, RobotState(n, now, tuple(q), (0.0,) * 6, torque, RobotStatus(1))
        )
        loop.tick(now, 0, timer)
        q = targets.sent[-1]  # the robot follows its targets exactly
    sent = np.array([q0, q0, *targets.sent])
    lower = safety_config.lower_rad()
    upper = safety_config.upper_rad()
    assert np.all(sent >= lower - 1e-12) and np.all(sent <= upper + 1e-12)
    velocity = np.diff(sent, axis=0) / 1e-3
    assert np.all(np.abs(velocity) <= np.array(safety_config.limits.velocity_max_rad_s) + 1e-9)
    acceleration = np.diff(velocity, axis=0) / 1e-3
    assert np.all(
        np.abs(acceleration) <= np.array(safety_config.limits.acceleration_max_rad_s2) + 1e-6
    )
