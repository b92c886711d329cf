"""The compiled trajectory samplers against each trajectory's own ``desired`` (the oracle)."""

import math
import types
from collections.abc import Callable
from functools import partial

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.robot import RobotModel
from hilrig.tick.trajectory import TRAJECTORIES, Start, Trajectory, make_trajectory
from hilrig.tick.trajectory_kernel import desired_writer

START = RobotModel().fk(np.array(HOME_Q_RAD))
OPTIONS: dict[str, list[dict[str, object]]] = {
    "circle": [{}, {"radius_m": 0.05, "period_s": 3.0, "ramp_s": 0.25, "normal": (0, 0, 1)}],
    "square": [{}, {"side_m": 0.1, "side_duration_s": 0.7}],
    "waypoints": [
        {"points": [(2.0, 0.05, 0.05, -0.05), (5.0, 0.0, -0.1, 0.05), (7.0, 0, 0, 0)]},
        {"points": [(0.0, 0, 0, 0), (0.5, 0.01, 0, 0)]},
    ],
    "hold": [{}],
}
CASES = [(name, options) for name in TRAJECTORIES for options in OPTIONS[name]]
TIMES = st.one_of(
    st.floats(-5.0, 60.0),
    st.floats(0.0, 1e7),
    st.sampled_from([0.0, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0, 7.0, 10.0, 10.5, -0.0]),
)


def is_compiled(write: Callable[[float], None]) -> bool:
    """Whether ``write`` calls machine code (a bound kernel), not a Python function."""
    return isinstance(write, partial) and not isinstance(write.func, types.FunctionType)


@pytest.mark.parametrize(("name", "options"), CASES)
@settings(max_examples=200, deadline=None)
@given(times=st.lists(TIMES, min_size=1, max_size=20))
def test_the_compiled_sampler_writes_what_desired_writes(
    name: str, options: dict[str, object], times: list[float]
) -> None:
    trajectory = make_trajectory(name, START, **options)
    got, expected = np.full(3, np.nan), np.full(3, np.nan)
    write = desired_writer(trajectory, got)
    assert is_compiled(write)
    for t_s in times:
        write(t_s)
        trajectory.desired(t_s, expected)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


class Line:
    """A trajectory hilrig does not compile: its own desired is called."""

    def __init__(self) -> None:
        self.start = Start.from_pose(START)

    @property
    def rotation(self) -> np.ndarray:
        return self.start.rotation

    @property
    def orientation(self) -> np.ndarray:
        return self.start.orientation

    @property
    def duration_s(self) -> float:
        return math.inf

    def desired(self, t_s: float, out_position_m: np.ndarray) -> None:
        out_position_m[:] = self.start.position_m
        out_position_m[0] += 0.01 * t_s


def test_another_trajectory_is_sampled_by_its_own_desired() -> None:
    line: Trajectory = Line()
    out = np.zeros(3)
    write = desired_writer(line, out)
    assert not is_compiled(write)
    write(2.0)
    assert out[0] == START[0, 3] + 0.02 and out[1] == START[1, 3]
