"""The hardware-in-the-loop rig: a 1 kHz admittance loop on the AUBO (or the emulated rig), its
recorder process and what a session needs around them.

The public API (names load on first use, so that ``import hilrig.rig`` stays light)::

    record_session(SessionConfig(...), live=...) -> SessionResult   # one recorded session
    RecorderFeed / RecorderProcess          # loop rows -> shared-memory rings -> MCAP
    LiveViewPort, LiveReportLike            # what a session needs of a live view
    ControlLoop, LoopConfig, Watchdog       # the loop itself
    RigProcess                              # the emulated rig in its own process
    ChildProcess                            # spawn + Ctrl-C mask + report Pipe + join/kill
    AXIS_NAMES, FT_DTYPE, JOINT_DTYPE, TICK_DTYPE   # the rows the loop hands the recorder
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hilrig.rig.child import START_METHOD, ChildProcess
    from hilrig.rig.kinds import RigKind
    from hilrig.rig.live_port import LiveReportLike, LiveViewPort
    from hilrig.rig.loop import ControlLoop, LoopConfig, Watchdog
    from hilrig.rig.loop_figures import LoopStatus, LoopSummary
    from hilrig.rig.recorder_feed import RecorderFeed
    from hilrig.rig.recorder_process import RecorderProcess, RecorderSummary
    from hilrig.rig.records import AXES, AXIS_NAMES, FT_DTYPE, JOINT_DTYPE, JOINTS, TICK_DTYPE
    from hilrig.rig.rig_process import FAULTS, RigProcess
    from hilrig.rig.rings import Rows
    from hilrig.rig.session import SessionResult, record_session
    from hilrig.rig.session_config import SessionConfig
    from hilrig.rig.view_feed import VIEW_RATE_HZ, ViewBatch, ViewCounts, ViewForwarder
    from hilrig.rig.virtual import VirtualInput

_MODULES = {
    "child": ("START_METHOD", "ChildProcess"),
    "kinds": ("RigKind",),
    "live_port": ("LiveReportLike", "LiveViewPort"),
    "loop": ("ControlLoop", "LoopConfig", "Watchdog"),
    "loop_figures": ("LoopStatus", "LoopSummary"),
    "recorder_feed": ("RecorderFeed",),
    "recorder_process": ("RecorderProcess", "RecorderSummary"),
    "records": ("AXES", "AXIS_NAMES", "FT_DTYPE", "JOINTS", "JOINT_DTYPE", "TICK_DTYPE"),
    "rig_process": ("FAULTS", "RigProcess"),
    "rings": ("Rows",),
    "session": ("SessionResult", "record_session"),
    "session_config": ("SessionConfig",),
    "view_feed": ("VIEW_RATE_HZ", "ViewBatch", "ViewCounts", "ViewForwarder"),
    "virtual": ("VirtualInput",),
}
_MODULE_OF = {name: module for module, names in _MODULES.items() for name in names}

__all__ = [
    "AXES",
    "AXIS_NAMES",
    "FAULTS",
    "FT_DTYPE",
    "JOINTS",
    "JOINT_DTYPE",
    "START_METHOD",
    "TICK_DTYPE",
    "VIEW_RATE_HZ",
    "ChildProcess",
    "ControlLoop",
    "LiveReportLike",
    "LiveViewPort",
    "LoopConfig",
    "LoopStatus",
    "LoopSummary",
    "RecorderFeed",
    "RecorderProcess",
    "RecorderSummary",
    "RigKind",
    "RigProcess",
    "Rows",
    "SessionConfig",
    "SessionResult",
    "ViewBatch",
    "ViewCounts",
    "ViewForwarder",
    "VirtualInput",
    "Watchdog",
    "record_session",
]


def __getattr__(name: str) -> object:
    """Load a public name's module on first use (numba, pinocchio, pandas come with some)."""
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value
