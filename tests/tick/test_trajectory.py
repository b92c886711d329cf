"""Task trajectories: closed forms, a smooth start, the workspace box and reachability by IK."""

import math
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.errors import ParameterError
from hilrig.robot import RobotModel
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.trajectory import (
    TRAJECTORIES,
    Circle,
    Trajectory,
    make_trajectory,
    minimum_jerk,
    ramped_time_s,
)

HOME = np.array(HOME_Q_RAD)
DT = 0.001
MODEL = RobotModel()
START = MODEL.fk(HOME)
START_M = START[:3, 3].copy()
EXAMPLE_OPTIONS: dict[str, dict[str, object]] = {
    "circle": {},
    "square": {},
    "waypoints": {"points": [(2.0, 0.05, 0.05, -0.05), (5.0, 0.0, -0.1, 0.05), (7.0, 0, 0, 0)]},
    "hold": {},
}


def sample(trajectory: Trajectory, times_s: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
    out = np.empty((len(times_s), 3))
    for row, t_s in zip(out, times_s, strict=True):
        trajectory.desired(float(t_s), row)
    return out


def one_lap_s(trajectory: Trajectory) -> NDArray[np.floating[Any]]:
    """Tick times of one lap at 1 kHz (at least one second)."""
    return np.arange(round(max(trajectory.duration_s, 1.0) / DT) + 1) * DT


@pytest.fixture(params=TRAJECTORIES)
def trajectory(request: pytest.FixtureRequest) -> Trajectory:
    return make_trajectory(request.param, START, **EXAMPLE_OPTIONS[request.param])


# --- closed forms -----------------------------------------------------------------------------


def test_circle_points_at_known_phases_are_on_the_circle_in_its_plane() -> None:
    circle = make_trajectory("circle", START)
    assert isinstance(circle, Circle)
    normal = np.array([1.0, 1.0, 0.3]) / math.sqrt(2.09)
    assert np.allclose(circle.normal, normal, rtol=0, atol=1e-15)
    centre, u, w = np.array(circle.centre_m), np.array(circle.u), np.array(circle.w)
    assert circle.radius_m == 0.1 and abs(u[2]) < 1e-15  # the start is on a horizontal radius
    out = np.empty(3)
    for k in range(1, 9):
        phase = k * math.pi / 4
        circle.desired(0.5 + 10.0 * k / 8, out)  # the 1 s ramp leaves the phase 0.5 s behind
        expected = centre + 0.1 * (math.cos(phase) * u + math.sin(phase) * w)
        assert np.allclose(out, expected, rtol=0, atol=1e-12)
        assert np.linalg.norm(out - centre) == pytest.approx(0.1, abs=1e-12)
        assert float((out - centre) @ normal) == pytest.approx(0.0, abs=1e-12)
    circle.desired(circle.duration_s, out)  # one full lap ends on the start
    assert np.allclose(out, START_M, rtol=0, atol=1e-12)
    assert circle.duration_s == 10.5


def test_circle_in_a_horizontal_plane_starts_on_the_circle() -> None:
    circle = make_trajectory("circle", START, normal=(0, 0, 2), radius_m=0.05, period_s=4)
    positions = sample(circle, np.arange(0, 4.5, 0.01))
    assert np.allclose(positions[:, 2], START_M[2], rtol=0, atol=1e-15)
    assert np.allclose(positions[0], START_M, rtol=0, atol=0)
    assert isinstance(circle, Circle)
    radii = np.linalg.norm(positions - np.array(circle.centre_m), axis=1)
    assert np.allclose(radii, 0.05, rtol=0, atol=1e-12)


def test_minimum_jerk_endpoints_midpoint_and_flat_ends() -> None:
    assert minimum_jerk(0.0) == 0.0 and minimum_jerk(1.0) == 1.0 and minimum_jerk(0.5) == 0.5
    h = 1e-4
    for end in (0.0, 1.0):
        side = 1.0 if end == 0.0 else -1.0
        s0, s1, s2 = (minimum_jerk(end + side * k * h) for k in range(3))
        assert abs(s1 - s0) / h < 1e-6  # velocity 0
        assert abs(s2 - 2 * s1 + s0) / h**2 < 1e-2  # acceleration 0: s'' = 60 h = 6e-3 at h


def test_ramped_clock_starts_at_rest_and_joins_the_real_clock() -> None:
    ramp = 1.0
    assert ramped_time_s(-1.0, ramp) == 0.0 and ramped_time_s(0.0, ramp) == 0.0
    assert ramped_time_s(ramp, ramp) == pytest.approx(0.5)
    assert ramped_time_s(3.0, ramp) == 2.5
    h = 1e-4
    rate_at_ramp = (ramped_time_s(ramp + h, ramp) - ramped_time_s(ramp - h, ramp)) / (2 * h)
    assert rate_at_ramp == pytest.approx(1.0, abs=1e-7)
    curvature_at_ramp = (
        ramped_time_s(ramp + h, ramp)
        - 2 * ramped_time_s(ramp, ramp)
        + ramped_time_s(ramp - h, ramp)
    ) / h**2
    assert abs(curvature_at_ramp) < 1e-3


def test_waypoints_hit_their_offsets_at_their_times_with_midpoints_halfway() -> None:
    points = [(1.0, 0.05, 0.05, -0.1), (3.0, 0.0, -0.1, 0.1)]
    path = make_trajectory("waypoints", START, points=points)
    offsets = [np.zeros(3)] + [np.array(p[1:]) for p in points]
    times = [0.0, 1.0, 3.0]
    out = np.empty(3)
    for t_s, offset in zip(times, offsets, strict=True):
        path.desired(t_s, out)
        assert np.allclose(out, START_M + offset, rtol=0, atol=1e-15)
    for k in range(2):
        path.desired((times[k] + times[k + 1]) / 2, out)
        assert np.allclose(out, START_M + (offsets[k] + offsets[k + 1]) / 2, rtol=0, atol=1e-15)
    for t_s, offset in ((-1.0, offsets[0]), (3.5, offsets[2]), (1e6, offsets[2])):
        path.desired(t_s, out)
        assert np.allclose(out, START_M + offset, rtol=0, atol=1e-15)
    assert path.duration_s == 3.0


def test_square_is_horizontal_visits_its_corners_and_repeats() -> None:
    square = make_trajectory("square", START, side_m=0.2, side_duration_s=2.5)
    corners = [(0, 0), (-0.2, 0), (-0.2, 0.2), (0, 0.2), (0, 0)]
    out = np.empty(3)
    for k, (dx, dy) in enumerate(corners):
        for lap in range(3):
            square.desired(2.5 * k + 10.0 * lap, out)
            assert np.allclose(out, START_M + np.array((dx, dy, 0.0)), rtol=0, atol=1e-12)
    positions = sample(square, np.arange(0, 20, 0.01))
    assert np.all(positions[:, 2] == START_M[2])
    later = sample(square, np.arange(0, 20, 0.01) + 10.0)
    assert np.allclose(later, positions, rtol=0, atol=1e-12)
    assert square.duration_s == 10.0


def test_hold_stays_at_the_start() -> None:
    hold = make_trajectory("hold", START)
    assert (sample(hold, np.array([-1.0, 0.0, 3.0, 1e9])) == START_M).all()
    assert hold.duration_s == 0.0


# --- every trajectory -------------------------------------------------------------------------


def test_every_trajectory_starts_on_the_start_at_rest(trajectory: Trajectory) -> None:
    h = 1e-4
    p0, p1, p2 = sample(trajectory, np.array([0.0, h, 2 * h]))
    assert np.array_equal(p0, START_M)
    assert np.linalg.norm(p1 - p0) / h < 1e-6  # m/s
    assert np.linalg.norm(p2 - 2 * p1 + p0) / h**2 < 1e-3  # m/s^2


def test_every_trajectory_has_continuous_velocity_and_acceleration(
    trajectory: Trajectory,
) -> None:
    positions = sample(trajectory, np.arange(-2, round(2 * trajectory.duration_s / DT) + 2) * DT)
    acceleration = np.diff(positions, 2, axis=0) / DT**2
    assert np.abs(acceleration).max() < 0.5  # m/s^2
    # a jump in velocity or acceleration would show as a spike in the change per tick
    assert np.abs(np.diff(acceleration, axis=0)).max() < 5e-3


def test_every_trajectory_keeps_the_fixed_start_orientation(trajectory: Trajectory) -> None:
    assert np.array_equal(trajectory.rotation, START[:3, :3])
    x, y, z, w = trajectory.orientation
    quaternion = pin.Quaternion(w, x, y, z)
    assert np.allclose(quaternion.toRotationMatrix(), START[:3, :3], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="read-only"):
        trajectory.rotation[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        trajectory.orientation[0] = 1.0


def test_every_trajectory_stays_inside_the_default_workspace_box(trajectory: Trajectory) -> None:
    config = SafetyConfig()
    positions = sample(trajectory, one_lap_s(trajectory))
    assert (positions >= config.workspace_min_m).all()
    assert (positions <= config.workspace_max_m).all()


def test_every_trajectory_is_reachable_by_warm_started_ik_for_a_lap(
    trajectory: Trajectory,
) -> None:
    pose = START.copy()
    pose[:3, :3] = trajectory.rotation
    q_rad = HOME.copy()
    for t_s in one_lap_s(trajectory):
        trajectory.desired(float(t_s), pose[:3, 3])
        result = MODEL.ik(pose, q_rad)
        assert result.converged, (t_s, result)
        q_rad = result.q_rad


def test_every_trajectory_passes_the_safety_clamp_untouched(trajectory: Trajectory) -> None:
    """Through tight IK (2 steps a tick), every joint command stays inside every clamp limit,
    the braking margin to the workspace box included."""
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    pose = START.copy()
    pose[:3, :3] = trajectory.rotation
    q_rad, out = HOME.copy(), np.empty(6)
    for t_s in one_lap_s(trajectory):
        trajectory.desired(float(t_s), pose[:3, 3])
        q_rad = MODEL.ik(pose, q_rad, tol_position_m=1e-10, tol_rotation_rad=1e-10).q_rad
        assert clamp.clamp(q_rad, out) == 0, t_s
        assert np.array_equal(out, q_rad)


# --- errors -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "options", "message"),
    [
        ("spiral", {}, "unknown trajectory 'spiral'; known: circle, square, waypoints, hold"),
        ("circle", {"radius": 0.1}, "unknown option"),
        ("hold", {"period_s": 1.0}, "accepted: none"),
        ("circle", {"radius_m": -0.1}, "radius_m must be a finite number > 0"),
        ("circle", {"period_s": math.nan}, "period_s"),
        ("circle", {"ramp_s": 0.0}, "ramp_s"),
        ("circle", {"radius_m": "0.1"}, "radius_m"),
        ("circle", {"normal": (0, 0, 0)}, "zero vector"),
        ("circle", {"normal": (1, 1)}, "3 finite numbers"),
        ("circle", {"normal": "xyz"}, "3 finite numbers"),
        ("square", {"side_m": math.inf}, "side_m"),
        ("square", {"side_duration_s": -1}, "side_duration_s"),
        ("waypoints", {}, "missing option\\(s\\) points"),
        ("waypoints", {"points": []}, "at least one"),
        ("waypoints", {"points": [(1.0, 0.0, 0.0)]}, "4 finite numbers"),
        ("waypoints", {"points": [(1.0, 0.0, 0.0, math.nan)]}, "4 finite numbers"),
        ("waypoints", {"points": [(0.0, 0.1, 0.0, 0.0)]}, "t = 0 must be"),
        ("waypoints", {"points": [(2.0, 0, 0, 0), (1.0, 0, 0, 0)]}, "must increase"),
        ("waypoints", {"points": [(-1.0, 0, 0, 0)]}, "must increase"),
    ],
)
def test_bad_names_and_options_raise_one_line(
    name: str, options: dict[str, object], message: str
) -> None:
    with pytest.raises(ParameterError, match=message) as error:
        make_trajectory(name, START, **options)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(
    "pose",
    [np.eye(3), np.full((4, 4), math.nan), np.diag([1.0, 1.0, -1.0, 1.0]), 2 * np.eye(4)],
)
def test_a_start_pose_that_is_not_rigid_is_refused(pose: NDArray[np.float64]) -> None:
    with pytest.raises(ParameterError, match="start pose"):
        make_trajectory("hold", pose)


def test_a_non_finite_time_is_refused(trajectory: Trajectory) -> None:
    with pytest.raises(ParameterError, match="finite"):
        trajectory.desired(math.nan, np.empty(3))
