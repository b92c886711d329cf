"""Which rig a session runs on and which interface drives its robot: a module of its own, so the
command line parses ``--rig`` and ``--robot-link`` without loading the rig."""

from enum import StrEnum


class RigKind(StrEnum):
    """Which rig a session runs on: the emulated one (started here) or a real AUBO."""

    EMULATED = "emulated"
    AUBO = "aubo"


class RobotLinkKind(StrEnum):
    """Which interface a session drives the robot through (:mod:`hilrig.rig.robot_links`)."""

    ARCS = "arcs"
    MODBUS = "modbus"
