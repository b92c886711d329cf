"""Which rig a session runs on: a module of its own, so the command line parses ``--rig``
without loading the rig."""

from enum import StrEnum


class RigKind(StrEnum):
    """Which rig a session runs on: the emulated one (started here) or a real AUBO."""

    EMULATED = "emulated"
    AUBO = "aubo"
