"""Volunteer models of the emulated rig: what a person does to the robot, over time.

A scenario gives the external wrench on the wrist sensor (sensor frame, N and N*m) given the
time and the sensor's pose, and the external joint torques (N*m) the joint modules measure, as
tuples of six floats: the rig calls them every 1 ms slot, so they are scalar code (the paper's
profiles evaluated segment by segment, bit-identical to their vectorised form). Times are seconds
since the scenario's clock started (a session's first tick; ``EmulatedRig.start_scenario``);
``period_s`` repeats the collision for long sessions.

- ``paper-end-effector``: eq. 15-17 at the tool (the paper applies them in the end-effector
  frame), collision from 4 s to 6 s.
- ``paper-body``: eq. 18-19 on joints 1 and 2, collision from 3.5 s to 5.5 s.
- ``hand-contact``: a hand, modelled as a spring-damper plane, moves into the tool's path,
  holds, and withdraws; the force depends on how far the robot has yielded, so the loop is
  closed through the person.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import HilrigError
from hilrig.paper.profiles import BODY_PROFILES, END_EFFECTOR_PROFILES, Profile

Wrench = tuple[float, float, float, float, float, float]
ZERO6: Wrench = (0.0,) * 6


def _at(profile: Profile, t_s: float) -> float:
    """``profile(t_s)`` for one time, in scalar code."""
    segments = profile.segments
    last = len(segments) - 1
    for index, seg in enumerate(segments):
        if seg.start_s <= t_s and (t_s <= seg.stop_s if index == last else t_s < seg.stop_s):
            return seg.slope * t_s + seg.intercept
    return 0.0


class Scenario(Protocol):
    """What a volunteer applies; each method is called from one emulator thread only."""

    name: str

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        """External wrench (Fx, Fy, Fz, Mx, My, Mz) on the wrist sensor, sensor frame."""
        ...

    def joint_torque(self, t_s: float) -> Wrench:
        """External torque on joints 1..6, N*m."""
        ...


def _local(t_s: float, period_s: float | None) -> float:
    return t_s % period_s if period_s else t_s


@dataclass
class PaperEndEffector:
    """Eq. 15-17 applied at the sensor, in its frame; repeats every ``period_s`` if given."""

    period_s: float | None = None
    name: str = "paper-end-effector"

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        t = _local(t_s, self.period_s)
        fx, fy, fz = (_at(profile, t) for profile in END_EFFECTOR_PROFILES)
        return (fx, fy, fz, 0.0, 0.0, 0.0)

    def joint_torque(self, t_s: float) -> Wrench:
        return ZERO6


@dataclass
class PaperBody:
    """Eq. 18-19 on joints 1 and 2; repeats every ``period_s`` if given."""

    period_s: float | None = None
    name: str = "paper-body"

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        return ZERO6

    def joint_torque(self, t_s: float) -> Wrench:
        t = _local(t_s, self.period_s)
        tau1, tau2 = (_at(profile, t) for profile in BODY_PROFILES)
        return (tau1, tau2, 0.0, 0.0, 0.0, 0.0)


@dataclass
class HandContact:
    """A hand pushing the tool along ``direction_in_base``, as a spring-damper plane.

    The hand plane starts ``gap_m`` short of the tool's position at rig start, moves at
    ``speed_m_s`` to ``depth_m`` past it from ``start_s``, holds ``hold_s``, and withdraws. In
    contact (penetration > 0) it pushes with ``stiffness_n_m * penetration + damping_n_s_m *
    penetration rate`` (never pulls) at ``contact_point_in_sensor`` (m), so the sensor also sees
    the moment of that force. The robot's yielding reduces the penetration: closed loop.
    """

    direction_in_base: tuple[float, float, float] = (0.0, 1.0, 0.0)
    start_s: float = 2.0
    gap_m: float = 0.05
    depth_m: float = 0.03
    speed_m_s: float = 0.1
    hold_s: float = 1.0
    stiffness_n_m: float = 300.0
    damping_n_s_m: float = 10.0
    contact_point_in_sensor: tuple[float, float, float] = (0.0, 0.0, 0.1)
    period_s: float | None = 10.0
    name: str = "hand-contact"
    _origin: tuple[float, float, float] | None = field(default=None, init=False, repr=False)
    _last: tuple[float, float] | None = field(default=None, init=False, repr=False)

    def hand_offset_m(self, t_s: float) -> float:
        """Where the hand plane is along the push direction, m past the tool's start position."""
        t = _local(t_s, self.period_s) - self.start_s
        travel_s = (self.gap_m + self.depth_m) / self.speed_m_s
        if t <= 0:
            return -self.gap_m
        if t < travel_s:
            return -self.gap_m + self.speed_m_s * t
        if t < travel_s + self.hold_s:
            return self.depth_m
        return max(-self.gap_m, self.depth_m - self.speed_m_s * (t - travel_s - self.hold_s))

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        norm = math.hypot(*self.direction_in_base)
        ux, uy, uz = (d / norm for d in self.direction_in_base)
        (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz) = pose_base_sensor[
            :3
        ].tolist()
        cx, cy, cz = self.contact_point_in_sensor
        contact = (
            px + r00 * cx + r01 * cy + r02 * cz,
            py + r10 * cx + r11 * cy + r12 * cz,
            pz + r20 * cx + r21 * cy + r22 * cz,
        )
        if self._origin is None:
            self._origin = contact
        ox, oy, oz = self._origin
        tool_along_m = (contact[0] - ox) * ux + (contact[1] - oy) * uy + (contact[2] - oz) * uz
        penetration_m = self.hand_offset_m(t_s) - tool_along_m
        rate_m_s = 0.0
        if self._last is not None and t_s > self._last[0]:
            rate_m_s = (penetration_m - self._last[1]) / (t_s - self._last[0])
        self._last = (t_s, penetration_m)
        if penetration_m <= 0.0:
            return ZERO6
        push_n = max(0.0, self.stiffness_n_m * penetration_m + self.damping_n_s_m * rate_m_s)
        bx, by, bz = push_n * ux, push_n * uy, push_n * uz  # the push in base, into sensor:
        fx = r00 * bx + r10 * by + r20 * bz
        fy = r01 * bx + r11 * by + r21 * bz
        fz = r02 * bx + r12 * by + r22 * bz
        return (fx, fy, fz, cy * fz - cz * fy, cz * fx - cx * fz, cx * fy - cy * fx)

    def joint_torque(self, t_s: float) -> Wrench:
        return ZERO6


@dataclass
class NoContact:
    """Nobody touches the robot (e.g. while a recorded collision is replayed virtually)."""

    name: str = "none"

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        return ZERO6

    def joint_torque(self, t_s: float) -> Wrench:
        return ZERO6


SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "none": NoContact,
    "paper-end-effector": PaperEndEffector,
    "paper-body": PaperBody,
    "hand-contact": HandContact,
}


def scenario(name: str) -> Scenario:
    """A fresh scenario called ``name``; raises HilrigError listing the known ones."""
    try:
        return SCENARIOS[name]()
    except KeyError:
        known = ", ".join(sorted(SCENARIOS))
        raise HilrigError(f"unknown scenario {name!r}; known: {known}") from None
