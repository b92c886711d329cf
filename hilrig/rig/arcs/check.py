"""An AUBO controller checked before a session (``hilrig doctor --robot HOST``): reachable, the
login accepted, its interface version, its robot and safety modes, and the RTDE rate it achieves
for the joint-state topic a session subscribes, counted over a few seconds.

It runs the session's own link (:class:`~hilrig.rig.arcs.link.ArcsLink`: AUBO's client in a
process of its own) and never enters servo mode: the arm does not move.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from hilrig.errors import LinkError
from hilrig.rig.arcs.link import ArcsJointStates, ArcsLink
from hilrig.rig.arcs.link_child import NORMAL, RUNNING, SAFETY_NAMES
from hilrig.rig.arcs.settings import ArcsSettings

SUPPORTED_INTERFACE = 24001  # the version AUBO's client 0.24.1 was observed to accept
ROBOT_MODE_NAMES = {
    -1: "no controller",
    0: "disconnected",
    1: "confirm safety",
    2: "booting",
    3: "power off",
    4: "power on",
    5: "idle",
    6: "brake releasing",
    7: "back drive",
    8: "running",
    9: "maintenance",
    10: "error",
    11: "powering off",
}


@dataclass(frozen=True)
class ControllerCheck:
    """What the check found; ``problem`` is "" when a session may start."""

    where: str
    error: str = ""  # the link could not come up (unreachable, login refused, ...)
    robot: str = ""
    interface_version: int = 0
    robot_mode: int = -1
    safety_mode: int = 0
    rtde_rate_hz: float = 0.0  # asked
    rtde_achieved_hz: float = 0.0  # counted
    rtde_samples: int = 0
    seconds: float = 0.0

    @property
    def problem(self) -> str:
        """The first reason a session would fail here ("" if none)."""
        if self.error:
            return self.error
        if self.robot_mode != RUNNING:
            return f"robot mode {self.robot_mode_name}: a session needs it running"
        if self.safety_mode != NORMAL:
            return f"safety mode {self.safety_mode_name}: a session needs it normal"
        if self.rtde_achieved_hz < 0.9 * self.rtde_rate_hz:
            return (
                f"RTDE delivered {self.rtde_achieved_hz:.1f} Hz of the {self.rtde_rate_hz:g} Hz "
                "asked: the joint states would go stale"
            )
        return ""

    @property
    def robot_mode_name(self) -> str:
        return ROBOT_MODE_NAMES.get(self.robot_mode, str(self.robot_mode))

    @property
    def safety_mode_name(self) -> str:
        return SAFETY_NAMES.get(self.safety_mode, str(self.safety_mode))


def check_controller(settings: ArcsSettings, seconds: float = 2.0) -> ControllerCheck:
    """Connect, log in, subscribe, count the joint states for ``seconds``, disconnect."""
    link = ArcsLink(settings)
    try:
        try:
            info = link.start()
        except LinkError as err:
            return ControllerCheck(settings.where(), error=str(err))
        states = ArcsJointStates(link)
        start = time.monotonic_ns()
        end = start + round(seconds * 1e9)
        first_ns = 0
        counted = 0
        while time.monotonic_ns() < end:
            time.sleep(0.01)
            rows = states.poll(time.monotonic_ns())
            if len(rows) and not first_ns:
                first_ns = int(rows[0]["t_ns"])
                counted -= 1  # the first sample opens the window
            counted += len(rows)
        last_ns = int(states.newest[0]["t_ns"])
        span_s = (last_ns - first_ns) / 1e9 if first_ns else 0.0
        return ControllerCheck(
            settings.where(),
            robot=str(info.get("robot", "")),
            interface_version=_int(info.get("interface_version")),
            robot_mode=_int(info.get("robot_mode"), -1),
            safety_mode=_int(info.get("safety_mode")),
            rtde_rate_hz=settings.rtde_rate_hz,
            rtde_achieved_hz=counted / span_s if span_s > 0 else 0.0,
            rtde_samples=states.samples,
            seconds=seconds,
        )
    finally:
        link.stop()


def _int(value: object, default: int = 0) -> int:
    return int(value) if isinstance(value, int | float) else default
