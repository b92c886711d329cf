"""Tasks inside the safety clamp's limits: every task, sampled at 1 kHz from rest as the loop
samples it and taken to the joints, keeps its joint velocity, acceleration and jerk (finite
differences, as the clamp differences its commands) within 80 % of the limits, or is refused in
one line that names the task, the joint, the limit and by how much."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.errors import ParameterError
from hilrig.robot import AUBO_I5_LIMITS, CompiledChain, RobotModel
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.task_limits import check_task
from hilrig.tick.trajectory import Trajectory, make_trajectory

DT = 0.001
MODEL = RobotModel()
Q0 = np.array(HOME_Q_RAD)
START = MODEL.fk(Q0)
LIMITS = np.array(
    [
        AUBO_I5_LIMITS.velocity_max_rad_s,
        AUBO_I5_LIMITS.acceleration_max_rad_s2,
        AUBO_I5_LIMITS.jerk_max_rad_s3,
    ]
)
WAYPOINTS = {"points": [(1.5, -0.05, 0.03, 0.02), (3.0, 0.0, 0.0, 0.0)]}
DEFAULTS = {"circle": {}, "square": {}, "waypoints": WAYPOINTS, "hold": {}}
# all of each task's motion from rest (s): circle ramp + one lap, four sides, the last point
SPANS = {"circle": 11.0, "square": 10.0, "waypoints": 3.0, "hold": 1.0}
REFUSAL = re.compile(
    r"trajectory '(\w+)': joint (\d) (velocity|acceleration|jerk) (\S+) rad/s\^?\d? is "
    r"(\d+) % over 80 % of its limit \((\S+) of (\S+) rad/s\^?\d?\); try .+"
)
QUANTITY_ROW = {"velocity": 0, "acceleration": 1, "jerk": 2}


def clamp() -> SafetyClamp:
    return SafetyClamp(SafetyConfig(), MODEL, Q0)


def joint_peaks(trajectory: Trajectory, span_s: float, *, pinocchio: bool) -> NDArray[np.float64]:
    """The oracle: positions from ``desired`` at k ms (three at rest before the start), joints
    by IK (pinocchio's, or the compiled one for speed), finite differences; (3, 6) peaks."""
    chain = CompiledChain.from_model(MODEL)
    solve = MODEL.ik if pinocchio else chain.ik
    pose, q = START.copy(), Q0.copy()
    path = [Q0, Q0, Q0]
    for k in range(1, math.ceil(span_s / DT) + 4):
        trajectory.desired(k * DT, pose[:3, 3])
        result = solve(pose, q, max_iterations=50, tol_position_m=1e-12, tol_rotation_rad=1e-12)
        assert result.converged, k
        q = result.q_rad
        path.append(q)
    v = np.diff(np.array(path), axis=0) / DT
    a = np.diff(v, axis=0) / DT
    jerk = np.diff(a, axis=0) / DT
    return np.array([np.abs(x).max(axis=0) for x in (v, a, jerk)])


@pytest.mark.parametrize("name", list(DEFAULTS))
def test_every_task_with_its_defaults_keeps_within_80_percent_of_the_limits(name: str) -> None:
    trajectory = make_trajectory(name, START, **DEFAULTS[name])
    found = check_task(name, trajectory, clamp())
    peaks = joint_peaks(trajectory, SPANS[name], pinocchio=True)
    assert np.all(peaks <= 0.8 * LIMITS), peaks / LIMITS
    # the same differences but for the IKs' rounding, which the jerk's third difference scales
    tolerance = np.array([[1e-6], [1e-3], [0.05]]) + 1e-3 * peaks
    assert np.all(np.abs(found.peaks - peaks) <= tolerance), found.peaks - peaks
    if name != "hold":  # every task but hold moves: a check that saw nothing would be wrong
        assert np.all(peaks.max(axis=1) > 0.01)


circles = st.fixed_dictionaries(
    {
        "radius_m": st.floats(0.02, 0.15),
        "period_s": st.floats(1.0, 12.0),
        "ramp_s": st.floats(0.05, 3.0),
        "normal": st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda n: math.hypot(*n) > 0.2),
    }
)
squares = st.fixed_dictionaries(
    {"side_m": st.floats(0.02, 0.25), "side_duration_s": st.floats(0.3, 4.0)}
)
offsets = st.tuples(st.floats(0.3, 3.0), *[st.floats(-0.12, 0.12)] * 3)
waypoint_paths = st.lists(offsets, min_size=1, max_size=3).map(
    lambda rows: {
        "points": [(sum(r[0] for r in rows[: k + 1]), *row[1:]) for k, row in enumerate(rows)]
    }
)


@settings(max_examples=30, deadline=None)
@given(
    task=st.one_of(
        circles.map(lambda o: ("circle", o)),
        squares.map(lambda o: ("square", o)),
        waypoint_paths.map(lambda o: ("waypoints", o)),
    )
)
def test_a_task_is_either_within_80_percent_or_refused_for_what_it_exceeds(
    task: tuple[str, dict[str, object]],
) -> None:
    name, options = task
    trajectory = make_trajectory(name, START, **options)
    span_s = trajectory.duration_s + (trajectory.ramp_s / 2 if name == "circle" else 0.0)
    try:
        check_task(name, trajectory, clamp())
    except ParameterError as refused:
        message = str(refused)
        match = REFUSAL.fullmatch(message)
        if match is None:  # refused for the clamp's bounds: reach, a joint's range, the box
            assert re.fullmatch(
                rf"trajectory '{name}' (leaves the arm's reach|takes a joint past its limit "
                r"\(less the clamp's margin and braking\)|leaves the safety clamp's workspace "
                r"box \(with its braking distance\)) at t = \S+ s, TCP \(\S+, \S+, \S+\) m",
                message,
            ), message
            t_s = float(message.split("at t = ")[1].split(" s")[0])
            named = message.split("TCP (")[1].split(")")[0].split(", ")
            position = np.zeros(3)
            trajectory.desired(t_s, position)
            np.testing.assert_allclose([float(x) for x in named], position, atol=6e-4)
            return
        joint, row = int(match[2]) - 1, QUANTITY_ROW[match[3]]
        peaks = joint_peaks(trajectory, span_s, pinocchio=False)
        assert peaks[row, joint] > 0.8 * LIMITS[row, joint]
        assert float(match[4]) == pytest.approx(peaks[row, joint], rel=6e-3)
        assert np.max(peaks / LIMITS) == pytest.approx(peaks[row, joint] / LIMITS[row, joint])
    else:
        peaks = joint_peaks(trajectory, span_s, pinocchio=False)
        assert np.all(peaks <= 0.8 * LIMITS * (1 + 1e-6)), peaks / LIMITS


@pytest.mark.parametrize(
    ("name", "options", "message"),
    [
        (
            "circle",
            {"period_s": 2.0},
            "trajectory 'circle': joint 4 acceleration 3.27 rad/s^2 is 36 % over 80 % of its "
            "limit (2.4 of 3 rad/s^2); try a longer period_s or ramp_s, or a smaller radius_m",
        ),
        (
            "circle",
            {"ramp_s": 0.1},
            "trajectory 'circle': joint 4 jerk 86.9 rad/s^3 is 262 % over 80 % of its limit "
            "(24 of 30 rad/s^3); try a longer period_s or ramp_s, or a smaller radius_m",
        ),
        (
            "square",
            {"side_duration_s": 0.5},
            "trajectory 'square': joint 3 jerk 293 rad/s^3 is 1120 % over 80 % of its limit "
            "(24 of 30 rad/s^3); try a longer side_duration_s or a shorter side_m",
        ),
        (
            "circle",
            {"radius_m": 0.3},
            "trajectory 'circle' leaves the safety clamp's workspace box (with its braking "
            "distance) at t = 1.803 s, TCP (0.541, -0.022, 0.079) m",
        ),
        (
            "waypoints",
            {"points": [(1.0, 0.5, 0.0, 0.0)]},
            "trajectory 'waypoints' leaves the arm's reach at t = 0.512 s, TCP (0.837, -0.121, "
            "0.293) m",
        ),
    ],
)
def test_a_task_beyond_the_limits_is_refused_in_one_line(
    name: str, options: dict[str, object], message: str
) -> None:
    with pytest.raises(ParameterError) as refused:
        check_task(name, make_trajectory(name, START, **options), clamp())
    assert str(refused.value) == message


def test_only_what_the_session_runs_of_a_task_is_checked() -> None:
    # gentle for 10 s, then 0.1 m in 0.3 s
    late = {"points": [(2.0, 0.05, 0.0, 0.0), (10.0, 0.0, 0.0, 0.0), (10.3, 0.1, 0.0, 0.0)]}
    trajectory = make_trajectory("waypoints", START, **late)
    check_task("waypoints", trajectory, clamp(), duration_s=9.0)
    with pytest.raises(ParameterError, match=r"^trajectory 'waypoints': joint \d "):
        check_task("waypoints", trajectory, clamp(), duration_s=11.0)
