"""The task trajectory sampled by one compiled call a tick, for the real-time loop.

:func:`desired_writer` turns a trajectory of :mod:`hilrig.tick.trajectory` into a call
``write(t_s)`` that writes its desired position into a given array, as ``desired`` does, but
without the Python of the closed forms (about a tenth of the tick's Python on a slow machine).
The circle and the waypoints (the square, and the hold: one point) each have their kernel; any
other :class:`~hilrig.tick.trajectory.Trajectory` keeps its own ``desired``. Checked against
``desired`` to 1e-12 m on any time (``tests/tick/test_trajectory_kernel.py``).

The loop's times are finite by construction; the compiled forms do not check them (``desired``
refuses a non-finite time with ParameterError).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.tick.trajectory import Circle, Hold, Trajectory, Waypoints
from hilrig.timing import bound_kernel

# circle_into's parameters, in this order
_CIRCLE_FIELDS = ("centre_m", "u", "w")


def desired_writer(
    trajectory: Trajectory, out_position_m: NDArray[np.float64]
) -> Callable[[float], None]:
    """``write(t_s)``: the desired TCP position (m, base frame) at ``t_s`` into ``out_position_m``
    (3,), compiled for the circle, the waypoints, the square and the hold."""
    if isinstance(trajectory, Circle):
        vectors = np.array([getattr(trajectory, name) for name in _CIRCLE_FIELDS], dtype=np.float64)
        scalars = np.array([trajectory.radius_m, trajectory.period_s, trajectory.ramp_s])
        return bound_kernel(circle_into, vectors, scalars, out_position_m, last=(0.0,))
    if isinstance(trajectory, Waypoints | Hold):
        path = (
            Waypoints(trajectory.start, (0.0,), (trajectory.start.position_m,), cyclic=False)
            if isinstance(trajectory, Hold)
            else trajectory
        )
        return bound_kernel(
            waypoints_into,
            np.array(path.times_s, dtype=np.float64),
            np.array(path.points_m, dtype=np.float64).reshape(-1, 3),
            path.cyclic,
            out_position_m,
            last=(0.0,),
        )
    return partial(_desired, trajectory, out_position_m)


def _desired(trajectory: Trajectory, out: NDArray[np.float64], t_s: float) -> None:
    trajectory.desired(t_s, out)


@njit(cache=True)
def circle_into(
    vectors: NDArray[np.float64],
    scalars: NDArray[np.float64],
    out: NDArray[np.float64],
    t_s: float,
) -> None:
    """Circle.desired: ``vectors`` the centre (m), u and w; ``scalars`` radius (m), period and
    ramp (s)."""
    radius, period, ramp = scalars[0], scalars[1], scalars[2]
    if t_s <= 0.0:
        ramped = 0.0
    elif t_s >= ramp:
        ramped = t_s - 0.5 * ramp
    else:
        tau = t_s / ramp
        ramped = ramp * tau**4 * (2.5 + tau * (-3.0 + tau))
    phase = 2.0 * math.pi * ramped / period
    a = radius * math.cos(phase)
    b = radius * math.sin(phase)
    for k in range(3):
        out[k] = vectors[0, k] + a * vectors[1, k] + b * vectors[2, k]


@njit(cache=True)
def waypoints_into(
    times: NDArray[np.float64],
    points: NDArray[np.float64],
    cyclic: bool,
    out: NDArray[np.float64],
    t_s: float,
) -> None:
    """Waypoints.desired: minimum-jerk between ``points`` (n, 3) at ``times`` (n,)."""
    last = times.shape[0] - 1
    if t_s >= times[last] and cyclic:
        t_s %= times[last]
    i = np.searchsorted(times, t_s, side="right") - 1  # bisect.bisect_right
    if i < 0 or i >= last:
        row = 0 if i < 0 else last
        for k in range(3):
            out[k] = points[row, k]
        return
    tau = (t_s - times[i]) / (times[i + 1] - times[i])
    s = tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau))
    for k in range(3):
        out[k] = points[i, k] + (points[i + 1, k] - points[i, k]) * s
