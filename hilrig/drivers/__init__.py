"""Device drivers: a folder per device, each with its wire format (``wire``, pure: no I/O, so it
can be fuzzed and replayed) and its link (``link``, the transport)::

    ft/             Kunwei wrist/base F/T sensor: wire, frames (its compiled framer into rows),
                    link (serial), gravity (tool load)
    robot_state/    the robot's joint-state stream: wire (HRS1 frames), frames (its compiled
                    decoder into rows), link (TCP client)
    joint_targets/  joint targets: wire (Modbus register map), frame (RTU request), link

Every link follows :mod:`hilrig.drivers.base`: ``connect()``/``close()`` (or ``with``), no thread of
its own: the caller's loop selects on ``fileno()`` and calls the non-blocking ``poll(now_ns)``; the
emulated rig (:mod:`hilrig.emulator`) speaks the same bytes; lost links reopen with
:class:`~hilrig.drivers.reconnect.Backoff`; health is a :class:`~hilrig.drivers.base.LinkStatus`.
The public names below load on first use (pyserial, pymodbus and numba come with some of them).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hilrig.drivers.base import Device, LinkStatus, Reader, Writer
    from hilrig.drivers.ft.frames import FtFrames
    from hilrig.drivers.ft.gravity import GravityCompensator, ToolLoad, identify_tool_load
    from hilrig.drivers.ft.link import FtSerial
    from hilrig.drivers.ft.wire import (
        SAMPLE_DTYPE,
        FramerConfig,
        FramerStats,
        FtSample,
        KunweiFramer,
    )
    from hilrig.drivers.joint_targets.link import JointTargetsWriter, ModbusEndpoint
    from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
    from hilrig.drivers.reconnect import Backoff
    from hilrig.drivers.robot_state.frames import StateFrames
    from hilrig.drivers.robot_state.link import RobotStateClient
    from hilrig.drivers.robot_state.wire import (
        STATE_DTYPE,
        RobotState,
        RobotStateDecoder,
        RobotStatus,
    )

_MODULES = {
    "base": ("Device", "LinkStatus", "Reader", "Writer"),
    "ft.gravity": ("GravityCompensator", "ToolLoad", "identify_tool_load"),
    "ft.frames": ("FtFrames",),
    "ft.link": ("FtSerial",),
    "ft.wire": ("SAMPLE_DTYPE", "FramerConfig", "FramerStats", "FtSample", "KunweiFramer"),
    "joint_targets.link": ("JointTargetsWriter", "ModbusEndpoint"),
    "joint_targets.wire": ("JointTargets", "Mode", "RegisterMap"),
    "reconnect": ("Backoff",),
    "robot_state.frames": ("StateFrames",),
    "robot_state.link": ("RobotStateClient",),
    "robot_state.wire": ("STATE_DTYPE", "RobotState", "RobotStateDecoder", "RobotStatus"),
}
_MODULE_OF = {name: module for module, names in _MODULES.items() for name in names}

__all__ = [
    "SAMPLE_DTYPE",
    "STATE_DTYPE",
    "Backoff",
    "Device",
    "FramerConfig",
    "FramerStats",
    "FtFrames",
    "FtSample",
    "FtSerial",
    "GravityCompensator",
    "JointTargets",
    "JointTargetsWriter",
    "KunweiFramer",
    "LinkStatus",
    "ModbusEndpoint",
    "Mode",
    "Reader",
    "RegisterMap",
    "RobotState",
    "RobotStateClient",
    "RobotStateDecoder",
    "RobotStatus",
    "StateFrames",
    "ToolLoad",
    "Writer",
    "identify_tool_load",
]


def __getattr__(name: str) -> object:
    """Load a public name's module on first use."""
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value
