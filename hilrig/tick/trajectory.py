"""Task trajectories X_d(t): where the TCP should be, in the base frame (m), t s after the start.

Every trajectory is built from the start TCP pose (4x4, base frame, m), so the loop starts on the
path, at rest: velocity and acceleration are zero at t = 0. The orientation stays the start's.

    trajectory = make_trajectory("circle", model.fk(q0_rad), radius_m=0.1)
    trajectory.desired(t_s, out_position_m)   # writes (3,) in place, m, base frame
    trajectory.rotation, trajectory.orientation   # 3x3 matrix; quaternion x y z w

Registry (``TRAJECTORIES``):

- ``circle``: the circle of the paper's section 3.4.1 in the plane with normal (1, 1, 0.3),
  radius 0.1 m by default. The paper's 0.2 m also fits around the AUBO-i5's home pose, but its
  lowest point comes within 48 mm of the default safety box's floor, less than the paper's
  vertical avoidance offset (37 mm) plus the safety clamp's braking margin at the circle's joint
  speeds (up to 35 mm); at 0.1 m the lowest point is 145 mm above the floor and the paper's
  offsets (up to 0.13 m) keep the TCP inside the box. The start lies on the circle at the end of
  its horizontal diameter; the phase runs one lap per ``period_s`` (10 s) after a ``ramp_s``
  (1 s) smooth start.
- ``square``: the paper's section 3.4.2 square, horizontal, side 0.2 m by default (the paper's
  0.3 m sides, at 2.5 s a side (one lap in its 10 s run), need up to 0.8 rad/s on joints 1 and 6
  from home; 0.2 m halves that). Corners are visited from the start toward the base (-x), then
  +y, +x and back, each side a rest-to-rest minimum-jerk move of ``side_duration_s`` (2.5 s);
  it repeats.
- ``waypoints``: ``points`` = [(t_s, dx, dy, dz), ...] offsets from the start (m) at times (s),
  minimum-jerk between them, at rest at each; it stays at the last point.
- ``hold``: the start pose.

A session runs a task only if it keeps inside the safety clamp's limits with margin
(:mod:`hilrig.tick.task_limits`); the loop samples it at t = k periods on tick k.

``desired`` creates no arrays. ``make_trajectory`` raises
:class:`~hilrig.errors.ParameterError` with a one-line message for an unknown name, an unknown
option, a bad option value or a start pose that is not a rigid transform.
"""

from __future__ import annotations

import bisect
import inspect
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from hilrig.errors import ParameterError

Vec3 = tuple[float, float, float]
PAPER_CIRCLE_NORMAL = (1.0, 1.0, 0.3)


class Trajectory(Protocol):
    """A task trajectory: the desired TCP position over time and a fixed orientation."""

    @property
    def rotation(self) -> NDArray[np.float64]:
        """The desired TCP orientation (3, 3) in the base frame; read-only."""
        ...

    @property
    def orientation(self) -> NDArray[np.float64]:
        """The same orientation as a unit quaternion (x, y, z, w); read-only."""
        ...

    @property
    def duration_s(self) -> float:
        """Time (s) of one lap, or of the whole path when it does not repeat (0 for hold)."""
        ...

    def desired(self, t_s: float, out_position_m: NDArray[np.float64]) -> None:
        """Write the desired TCP position (3,), base frame, m, at ``t_s`` s after the start.

        Before the start (``t_s <= 0``) it is the start position. Raises
        :class:`~hilrig.errors.ParameterError` for a time that is not finite.
        """
        ...


@dataclass(frozen=True, slots=True)
class Start:
    """The start TCP pose: position (m) and orientation in the base frame, read-only arrays."""

    position_m: Vec3
    rotation: NDArray[np.float64]
    orientation: NDArray[np.float64]

    @classmethod
    def from_pose(cls, pose: NDArray[np.float64]) -> Start:
        """From a 4x4 pose; raises ParameterError unless it is a finite rigid transform."""
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise ParameterError(f"start pose must be a finite 4x4 matrix, got shape {pose.shape}")
        rotation = pose[:3, :3].copy()
        if (
            not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6)
            or np.linalg.det(rotation) <= 0
        ):
            raise ParameterError("start pose: the upper-left 3x3 block is not a rotation")
        quaternion = np.array(pin.Quaternion(rotation).coeffs(), dtype=np.float64)
        rotation.flags.writeable = False
        quaternion.flags.writeable = False
        x, y, z = pose[:3, 3].tolist()
        return cls((x, y, z), rotation, quaternion)


def _check_time(t_s: float) -> None:
    if not math.isfinite(t_s):
        raise ParameterError(f"trajectory time t_s must be finite, got {t_s}")


def minimum_jerk(tau: float) -> float:
    """The rest-to-rest minimum-jerk blend s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 on [0, 1].

    s(0) = 0, s(1) = 1, and its first and second derivatives vanish at both ends.
    """
    return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau))


def ramped_time_s(t_s: float, ramp_s: float) -> float:
    """A clock (s) that starts at rest: its rate rises from 0 to 1 over ``ramp_s`` along the
    minimum-jerk blend, so its first and second derivatives are 0 at t = 0; from ``ramp_s`` on it
    runs at rate 1, ``ramp_s / 2`` behind t.
    """
    if t_s <= 0.0:
        return 0.0
    if t_s >= ramp_s:
        return t_s - 0.5 * ramp_s
    tau = t_s / ramp_s  # the integral of minimum_jerk: ramp_s * (2.5 tau^4 - 3 tau^5 + tau^6)
    return ramp_s * tau**4 * (2.5 + tau * (-3.0 + tau))


class _StartOrientation:
    """The fixed orientation every trajectory keeps: its start pose's."""

    __slots__ = ()
    start: Start

    @property
    def rotation(self) -> NDArray[np.float64]:
        return self.start.rotation

    @property
    def orientation(self) -> NDArray[np.float64]:
        return self.start.orientation


@dataclass(frozen=True, slots=True)
class Hold(_StartOrientation):
    """Stay at the start pose."""

    start: Start

    @property
    def duration_s(self) -> float:
        return 0.0

    def desired(self, t_s: float, out_position_m: NDArray[np.float64]) -> None:
        _check_time(t_s)
        out_position_m[0], out_position_m[1], out_position_m[2] = self.start.position_m


@dataclass(frozen=True, slots=True)
class Circle(_StartOrientation):
    """A circle through the start: centre (m), unit plane normal, radius (m), period (s).

    Position at phase phi: ``centre + radius (cos(phi) u + sin(phi) w)`` with ``u`` the unit
    vector from the centre to the start and ``w = normal x u`` the direction of travel at the
    start; ``phi = 2 pi ramped_time_s(t, ramp_s) / period_s``.
    """

    start: Start
    centre_m: Vec3
    normal: Vec3
    radius_m: float
    period_s: float
    ramp_s: float
    u: Vec3
    w: Vec3

    @property
    def duration_s(self) -> float:
        """The first lap ends ``ramp_s / 2`` after one period: the ramp's lost time."""
        return self.period_s + 0.5 * self.ramp_s

    def desired(self, t_s: float, out_position_m: NDArray[np.float64]) -> None:
        _check_time(t_s)
        phase = 2.0 * math.pi * ramped_time_s(t_s, self.ramp_s) / self.period_s
        a = self.radius_m * math.cos(phase)
        b = self.radius_m * math.sin(phase)
        (cx, cy, cz), (ux, uy, uz), (wx, wy, wz) = self.centre_m, self.u, self.w
        out_position_m[0] = cx + a * ux + b * wx
        out_position_m[1] = cy + a * uy + b * wy
        out_position_m[2] = cz + a * uz + b * wz


@dataclass(frozen=True, slots=True)
class Waypoints(_StartOrientation):
    """Rest-to-rest minimum-jerk moves through positions (m, base frame) at times (s).

    ``times_s`` starts at 0 with the start position; a ``cyclic`` path (last point = first)
    repeats with period ``duration_s``, otherwise it stays at the last point.
    """

    start: Start
    times_s: tuple[float, ...]
    points_m: tuple[Vec3, ...]
    cyclic: bool

    @property
    def duration_s(self) -> float:
        return self.times_s[-1]

    def desired(self, t_s: float, out_position_m: NDArray[np.float64]) -> None:
        _check_time(t_s)
        times = self.times_s
        if t_s >= times[-1] and self.cyclic:
            t_s %= times[-1]
        i = bisect.bisect_right(times, t_s) - 1
        if i < 0 or i >= len(times) - 1:
            point = self.points_m[0 if i < 0 else -1]
            out_position_m[0], out_position_m[1], out_position_m[2] = point
            return
        s = minimum_jerk((t_s - times[i]) / (times[i + 1] - times[i]))
        (ax, ay, az), (bx, by, bz) = self.points_m[i], self.points_m[i + 1]
        out_position_m[0] = ax + (bx - ax) * s
        out_position_m[1] = ay + (by - ay) * s
        out_position_m[2] = az + (bz - az) * s


_Number = int | float | np.integer | np.floating


def _positive(name: str, value: object) -> float:
    if isinstance(value, _Number) and math.isfinite(value) and value > 0:
        return float(value)
    raise ParameterError(f"trajectory option {name} must be a finite number > 0, got {value!r}")


def _vector(name: str, value: object, size: int) -> tuple[float, ...]:
    items = list(value) if isinstance(value, Sequence | np.ndarray) else []
    numbers = tuple(float(x) for x in items if isinstance(x, _Number) and math.isfinite(x))
    if len(items) != size or len(numbers) != size:
        raise ParameterError(
            f"trajectory option {name} must be {size} finite numbers, got {value!r}"
        )
    return numbers


def _offset(start: Start, dx: float, dy: float, dz: float) -> Vec3:
    x, y, z = start.position_m
    return (x + dx, y + dy, z + dz)


def circle(
    start: Start,
    *,
    radius_m: float = 0.1,
    period_s: float = 10.0,
    ramp_s: float = 1.0,
    normal: Sequence[float] = PAPER_CIRCLE_NORMAL,
) -> Circle:
    """The circle (see the module docstring): the centre lies ``radius_m`` from the start along
    ``-u``, with ``u`` the horizontal in-plane direction ``normal x z`` (``normal x y`` for a
    horizontal plane), normalised."""
    radius_m = _positive("radius_m", radius_m)
    period_s = _positive("period_s", period_s)
    ramp_s = _positive("ramp_s", ramp_s)
    n = np.array(_vector("normal", normal, 3))
    if not np.linalg.norm(n) > 0.0:
        raise ParameterError("trajectory option normal must not be the zero vector")
    n /= np.linalg.norm(n)
    u = np.cross(n, (0.0, 0.0, 1.0))
    if np.linalg.norm(u) < 1e-9:  # a horizontal plane
        u = np.cross(n, (0.0, 1.0, 0.0))
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    centre = np.array(start.position_m) - radius_m * u
    return Circle(start, _vec3(centre), _vec3(n), radius_m, period_s, ramp_s, _vec3(u), _vec3(w))


def square(start: Start, *, side_m: float = 0.2, side_duration_s: float = 2.5) -> Waypoints:
    """The horizontal square (see the module docstring), repeating every 4 sides."""
    s = _positive("side_m", side_m)
    dt = _positive("side_duration_s", side_duration_s)
    corners = ((0.0, 0.0), (-s, 0.0), (-s, s), (0.0, s), (0.0, 0.0))
    return Waypoints(
        start,
        tuple(k * dt for k in range(5)),
        tuple(_offset(start, dx, dy, 0.0) for dx, dy in corners),
        cyclic=True,
    )


def waypoints(start: Start, *, points: Sequence[Sequence[float]]) -> Waypoints:
    """Through ``points`` = [(t_s, dx, dy, dz), ...] (s; m from the start, base axes).

    Times must increase strictly from >= 0; a point at t = 0 must be the start (zero offset).
    """
    rows = [_vector(f"points[{k}]", row, 4) for k, row in enumerate(points)]
    if not rows:
        raise ParameterError("trajectory option points must hold at least one (t_s, x, y, z)")
    if rows[0][0] == 0.0:
        if rows[0][1:] != (0.0, 0.0, 0.0):
            raise ParameterError("trajectory option points: the point at t = 0 must be (0, 0, 0)")
    else:
        rows.insert(0, (0.0, 0.0, 0.0, 0.0))
    times = tuple(row[0] for row in rows)
    if not all(t1 > t0 for t0, t1 in itertools.pairwise(times)) or times[0] < 0.0:
        raise ParameterError(f"trajectory option points: times must increase from 0, got {times}")
    return Waypoints(start, times, tuple(_offset(start, *row[1:]) for row in rows), cyclic=False)


def hold(start: Start) -> Hold:
    """The start pose, forever."""
    return Hold(start)


def _vec3(values: NDArray[np.float64]) -> Vec3:
    return float(values[0]), float(values[1]), float(values[2])


_BUILDERS: dict[str, Callable[..., Trajectory]] = {
    "circle": circle,
    "square": square,
    "waypoints": waypoints,
    "hold": hold,
}
TRAJECTORIES: tuple[str, ...] = tuple(_BUILDERS)


def make_trajectory(name: str, start_pose: NDArray[np.float64], **options: object) -> Trajectory:
    """The trajectory ``name`` (one of TRAJECTORIES) from the start TCP pose (4x4, base, m).

    ``options`` are the builder's keywords (see :func:`circle`, :func:`square`,
    :func:`waypoints`). Raises :class:`~hilrig.errors.ParameterError` (one line) for an unknown
    name or option, a bad option value, or a start pose that is not a rigid transform.
    """
    builder = _BUILDERS.get(name)
    if builder is None:
        raise ParameterError(f"unknown trajectory {name!r}; known: {', '.join(TRAJECTORIES)}")
    parameters = dict(inspect.signature(builder).parameters)
    del parameters["start"]
    unknown = sorted(set(options) - set(parameters))
    if unknown:
        raise ParameterError(
            f"trajectory {name!r}: unknown option(s) {', '.join(unknown)}; "
            f"accepted: {', '.join(parameters) or 'none'}"
        )
    required = inspect.Parameter.empty
    missing = [p for p, spec in parameters.items() if spec.default is required and p not in options]
    if missing:
        raise ParameterError(f"trajectory {name!r}: missing option(s) {', '.join(missing)}")
    return builder(Start.from_pose(start_pose), **options)
