"""Volunteer models of the emulated rig: what a person does to the robot, over time.

A scenario gives the external wrench on the wrist sensor (sensor frame, N and N*m) given the
time and the sensor's pose, and the external joint torques (N*m) the joint modules measure, as
tuples of six floats: the rig calls them every 1 ms slot, so they are scalar code (the paper's
profiles evaluated segment by segment, bit-identical to their vectorised form). Times are seconds
since the scenario's clock started (a session's first tick; ``EmulatedRig.start_scenario``);
``period_s`` repeats the collision for long sessions.

Every field of a scenario but its name is a setting (``make_scenario(name, {"stiffness_n_m":
"800"})``, ``hilrig record --scenario-set``): text or TOML values are parsed by the field's
type, unknown keys and values out of range are refused in one line naming the scenario, the
setting and the value (:class:`~hilrig.errors.ParameterError`), and :func:`settings_of` gives
the values a session records.

- ``paper-end-effector``: eq. 15-17 at the tool (the paper applies them in the end-effector
  frame), collision from 4 s to 6 s.
- ``paper-body``: eq. 18-19 on joints 1 and 2, collision from 3.5 s to 5.5 s.
- ``hand-contact``: a hand, modelled as a spring-damper plane, comes to the tool wherever the
  task has moved it, presses into it, holds, and withdraws; the force depends on how far the
  robot has yielded, so the loop is closed through the person.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import Field, dataclass, field, fields
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import ParameterError
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


def _doc(text: str) -> dict[str, str]:
    return {"doc": text}


PERIOD_DOC = "repeat the collision every this many s; none: once"


@dataclass
class PaperEndEffector:
    """Eq. 15-17 applied at the sensor, in its frame; repeats every ``period_s`` if given."""

    period_s: float | None = field(default=None, metadata=_doc(PERIOD_DOC))
    name: str = field(default="paper-end-effector", init=False)

    def __post_init__(self) -> None:
        _check_period(self.name, self.period_s, _profiles_end_s(END_EFFECTOR_PROFILES))

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        t = _local(t_s, self.period_s)
        fx, fy, fz = (_at(profile, t) for profile in END_EFFECTOR_PROFILES)
        return (fx, fy, fz, 0.0, 0.0, 0.0)

    def joint_torque(self, t_s: float) -> Wrench:
        return ZERO6


@dataclass
class PaperBody:
    """Eq. 18-19 on joints 1 and 2; repeats every ``period_s`` if given."""

    period_s: float | None = field(default=None, metadata=_doc(PERIOD_DOC))
    name: str = field(default="paper-body", init=False)

    def __post_init__(self) -> None:
        _check_period(self.name, self.period_s, _profiles_end_s(BODY_PROFILES))

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        return ZERO6

    def joint_torque(self, t_s: float) -> Wrench:
        t = _local(t_s, self.period_s)
        tau1, tau2 = (_at(profile, t) for profile in BODY_PROFILES)
        return (tau1, tau2, 0.0, 0.0, 0.0, 0.0)


@dataclass
class HandContact:
    """A hand pushing the tool along ``direction_in_base``, as a spring-damper plane.

    The hand plane stays ``gap_m`` short of the tool, following it as the task moves it, until
    ``start_s``; then it closes in at ``speed_m_s``. From the moment it reaches the tool it moves
    on alone, on a fixed line from where it met the tool: to ``depth_m`` past that point, holds
    ``hold_s``, and withdraws at ``speed_m_s``; once back short of the tool it follows it again.
    So it meets the tool on any task, and where the tool goes after that (yielding, or the
    task's own motion) changes how far the hand presses in. In contact (penetration > 0) it
    pushes with ``stiffness_n_m * penetration + damping_n_s_m * penetration rate`` (never
    pulls) at ``contact_point_in_sensor`` (m), so the sensor also sees the moment of that force.
    The robot's yielding reduces the penetration: closed loop.
    """

    direction_in_base: tuple[float, float, float] = field(
        default=(0.0, 1.0, 0.0),
        metadata=_doc("the push's direction, base frame, x,y,z"),
    )
    start_s: float = field(default=2.0, metadata=_doc("when the hand starts to move, s"))
    gap_m: float = field(default=0.05, metadata=_doc("how far short of the tool the hand waits, m"))
    depth_m: float = field(
        default=0.03, metadata=_doc("how far past where it meets the tool it goes, m")
    )
    speed_m_s: float = field(default=0.1, metadata=_doc("its approach and withdrawal speed, m/s"))
    hold_s: float = field(default=1.0, metadata=_doc("how long it holds at its depth, s"))
    stiffness_n_m: float = field(default=300.0, metadata=_doc("the hand's stiffness, N/m"))
    damping_n_s_m: float = field(default=10.0, metadata=_doc("the hand's damping, N*s/m"))
    contact_point_in_sensor: tuple[float, float, float] = field(
        default=(0.0, 0.0, 0.1), metadata=_doc("where it pushes, sensor frame, x,y,z, m")
    )
    period_s: float | None = field(default=10.0, metadata=_doc(PERIOD_DOC))
    name: str = field(default="hand-contact", init=False)
    _met_m: float | None = field(default=None, init=False, repr=False)
    _last: tuple[float, float] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        where = f"scenario {self.name}"
        for key in ("start_s", "gap_m", "hold_s", "stiffness_n_m", "damping_n_s_m"):
            _check_at_least(where, key, getattr(self, key), 0.0)
        for key in ("depth_m", "speed_m_s"):
            _check_at_least(where, key, getattr(self, key), 0.0, strictly=True)
        for key in ("direction_in_base", "contact_point_in_sensor"):
            if not all(math.isfinite(v) for v in getattr(self, key)):
                raise ParameterError(f"{where}: {key} {getattr(self, key)} must be finite")
        if math.hypot(*self.direction_in_base) == 0.0:
            raise ParameterError(f"{where}: direction_in_base (0, 0, 0) has no direction")
        _check_period(self.name, self.period_s, self.duration_s)

    @property
    def duration_s(self) -> float:
        """From the period's start to the hand back at its start (approach, hold, withdrawal)."""
        return self.start_s + 2 * (self.gap_m + self.depth_m) / self.speed_m_s + self.hold_s

    def hand_offset_m(self, t_s: float) -> float:
        """Where the hand plane is along the push direction, m past where it meets the tool
        (negative: short of the tool, which it then follows)."""
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
        tool_m = contact[0] * ux + contact[1] * uy + contact[2] * uz  # along the push
        offset_m = self.hand_offset_m(t_s)
        if offset_m <= 0.0 or self._met_m is None:  # short of the tool: it follows the tool
            self._met_m = tool_m
        penetration_m = offset_m - (tool_m - self._met_m)
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

    name: str = field(default="none", init=False)

    def wrench_in_sensor(self, t_s: float, pose_base_sensor: NDArray[np.float64]) -> Wrench:
        return ZERO6

    def joint_torque(self, t_s: float) -> Wrench:
        return ZERO6


#: The ISO/TS 15066 body region each volunteer touches the robot with (hilrig.world.body): the
#: paper's end-effector forces and the hand model are a person's hand; the paper's body torques
#: name no contact force.
DEFAULT_BODY_REGION = {"hand-contact": "hand", "paper-end-effector": "hand"}

SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "none": NoContact,
    "paper-end-effector": PaperEndEffector,
    "paper-body": PaperBody,
    "hand-contact": HandContact,
}


def scenario(name: str, settings: Mapping[str, object] | None = None) -> Scenario:
    """A fresh scenario called ``name`` with ``settings`` (text as on the command line, or TOML
    values); raises ParameterError (one line) for an unknown scenario (listing the known ones),
    an unknown setting (listing the scenario's) or a bad value."""
    try:
        factory = SCENARIOS[name]
    except KeyError:
        known = ", ".join(sorted(SCENARIOS))
        raise ParameterError(f"unknown scenario {name!r}; known: {known}") from None
    settable = {f.name: f for f in settings_fields(name)}
    values: dict[str, Any] = {}
    for key, raw in (settings or {}).items():
        if key not in settable:
            known = ", ".join(settable) or "none"
            raise ParameterError(f"scenario {name}: no setting {key!r}; its settings: {known}")
        values[key] = _parse(name, settable[key], raw)
    return factory(**values)


def settings_fields(name: str) -> tuple[Field[Any], ...]:
    """The settable fields of scenario ``name`` (all but its name and inner state)."""
    return tuple(f for f in fields(SCENARIOS[name])  # type: ignore[arg-type]
                 if f.init)  # fmt: skip


def settings_of(volunteer: Scenario) -> dict[str, float | list[float] | None]:
    """The values of ``volunteer``'s settings, as JSON takes them (vectors as lists)."""
    values: dict[str, float | list[float] | None] = {}
    for f in settings_fields(volunteer.name):
        value = getattr(volunteer, f.name)
        values[f.name] = list(value) if isinstance(value, tuple) else value
    return values


def describe_settings(name: str) -> str:
    """``key=default (what it is)`` for each setting of ``name``, for ``--help``."""
    parts = []
    for f in settings_fields(name):
        default = f.default
        shown = (
            "none"
            if default is None
            else (
                ",".join(f"{v:g}" for v in default)
                if isinstance(default, tuple)
                else f"{default:g}"
            )
        )
        parts.append(f"{f.name}={shown} ({f.metadata['doc']})")
    return "; ".join(parts) or "no settings"


def settings_help() -> str:
    """Every scenario's settings, for ``hilrig record --help`` (hilrig.cli.options keeps a copy)."""
    return " ".join(f"{name}: {describe_settings(name)}." for name in sorted(SCENARIOS))


def _parse(name: str, spec: Field[Any], raw: object) -> float | tuple[float, ...] | None:
    """``raw`` as ``spec``'s type: a number, ``x,y,z`` (or a list of 3), or ``none``."""
    where = f"scenario {name}: {spec.name}"
    kind = str(spec.type)
    if "None" in kind and (
        raw is None or (isinstance(raw, str) and raw.strip().lower() in ("none", "off", ""))
    ):
        return None
    if kind.startswith("tuple"):
        items = raw.split(",") if isinstance(raw, str) else raw
        if not isinstance(items, list | tuple) or len(items) != 3:
            raise ParameterError(f"{where} {raw!r} is not three numbers x,y,z")
        return tuple(_number(where, item) for item in items)
    return _number(where, raw)


def _number(where: str, raw: object) -> float:
    try:
        value = float(raw.strip() if isinstance(raw, str) else raw)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ParameterError(f"{where} {raw!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"{where} {raw!r} is not a finite number")
    return value


def _check_at_least(
    where: str, key: str, value: float, low: float, *, strictly: bool = False
) -> None:
    if not (value > low if strictly else value >= low):
        raise ParameterError(
            f"{where}: {key} {value:g} must be {'>' if strictly else '>='} {low:g}"
        )


def _check_period(name: str, period_s: float | None, collision_s: float) -> None:
    """A repeat period must hold the whole collision."""
    if period_s is not None and not period_s >= collision_s:
        raise ParameterError(
            f"scenario {name}: period_s {period_s:g} is shorter than its collision"
            f" ({collision_s:g} s from the period's start)"
        )


def _profiles_end_s(profiles: tuple[Profile, ...]) -> float:
    return max(profile.segments[-1].stop_s for profile in profiles)
