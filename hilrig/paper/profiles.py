"""The paper's collision inputs, eq. (15)-(19), with the signs of docs/paper-reproduction.md.

Every profile is piecewise linear in time, zero outside its support and continuous everywhere
(the pieces meet at their breakpoints and at the support's ends). Time is in seconds, forces in
N (end effector, Cartesian x, y, z) and torques in N*m (joints 1..6).

    fx: -5t + 20 on [4, 5);  5t - 30 on [5, 6]
    fy: 35t/3 - 140/3 on [4, 4.3);  3.5 on [4.3, 5.6);  -8.75t + 52.5 on [5.6, 6]
    fz: -3t + 12 on [4, 4.5);  -10t/7 + 69/14 on [4.5, 5.2);  3.125t - 18.75 on [5.2, 6]
    tau1 = tau2: 10t - 35 on [3.5, 4);  5 on [4, 5);  -10t + 55 on [5, 5.5];  tau3..tau6 = 0
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

END_EFFECTOR_ONSET_S = 4.0  # the end-effector collision starts (eq. 15-17)
END_EFFECTOR_RELEASE_S = 6.0  # ... and ends
BODY_ONSET_S = 3.5  # the body collision starts (eq. 18-19)
BODY_RELEASE_S = 5.5  # ... and ends
JOINTS = 6


@dataclass(frozen=True)
class Segment:
    """``slope * t + intercept`` on ``[start_s, stop_s)`` (closed at stop_s if it is the last)."""

    start_s: float
    stop_s: float
    slope: float
    intercept: float


@dataclass(frozen=True)
class Profile:
    """A piecewise-linear input of time, zero outside its contiguous segments.

    Calling it evaluates it (vectorised) at times ``t_s`` in seconds; the unit of the values is
    the profile's (N or N*m).
    """

    name: str
    segments: tuple[Segment, ...]

    def __call__(self, t_s: ArrayLike) -> NDArray[np.float64]:
        t = np.asarray(t_s, dtype=np.float64)
        value = np.zeros_like(t)
        last = len(self.segments) - 1
        for index, seg in enumerate(self.segments):
            before_stop = t <= seg.stop_s if index == last else t < seg.stop_s
            inside = (t >= seg.start_s) & before_stop
            value = np.where(inside, seg.slope * t + seg.intercept, value)
        return value

    @property
    def breakpoints_s(self) -> tuple[float, ...]:
        """Start of every segment and the end of the last one, s."""
        return (*(seg.start_s for seg in self.segments), self.segments[-1].stop_s)


fx = Profile("fx", (Segment(4.0, 5.0, -5.0, 20.0), Segment(5.0, 6.0, 5.0, -30.0)))
fy = Profile(
    "fy",
    (
        Segment(4.0, 4.3, 35.0 / 3.0, -140.0 / 3.0),
        Segment(4.3, 5.6, 0.0, 3.5),
        Segment(5.6, 6.0, -8.75, 52.5),
    ),
)
fz = Profile(
    "fz",
    (
        Segment(4.0, 4.5, -3.0, 12.0),
        Segment(4.5, 5.2, -10.0 / 7.0, 69.0 / 14.0),
        Segment(5.2, 6.0, 3.125, -18.75),
    ),
)
tau1 = Profile(
    "tau1",
    (Segment(3.5, 4.0, 10.0, -35.0), Segment(4.0, 5.0, 0.0, 5.0), Segment(5.0, 5.5, -10.0, 55.0)),
)
tau2 = Profile("tau2", tau1.segments)

END_EFFECTOR_PROFILES = (fx, fy, fz)
BODY_PROFILES = (tau1, tau2)  # tau3..tau6 are zero


def end_effector_force(t_s: ArrayLike) -> NDArray[np.float64]:
    """The end-effector collision force (T, 3): columns fx, fy, fz in N at times t_s (s)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    return np.stack([profile(t) for profile in END_EFFECTOR_PROFILES], axis=1)


def joint_torque(t_s: ArrayLike) -> NDArray[np.float64]:
    """The body collision torque (T, 6): tau1..tau6 in N*m at times t_s (s), tau3..tau6 = 0."""
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    torque = np.zeros((t.shape[0], JOINTS))
    for column, profile in enumerate(BODY_PROFILES):
        torque[:, column] = profile(t)
    return torque
