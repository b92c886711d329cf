"""Device protocols: the wrist/base F/T sensors (serial), robot joint state (TCP), joint targets.

Every driver follows :mod:`hilrig.drivers.base`: ``connect()``/``close()`` (or ``with``), no
thread of its own: the caller's loop selects on ``fileno()`` and calls the non-blocking
``poll(now_ns)``; lost links reopen with :class:`~hilrig.drivers.reconnect.Backoff`; health is a
:class:`~hilrig.drivers.base.LinkStatus`.
Wire formats are pure modules (no I/O) so they can be fuzzed and replayed; the emulated rig in
:mod:`hilrig.drivers.emulated` speaks the same bytes over a pty and loopback sockets.
"""

from hilrig.drivers.base import Device, LinkStatus, Reader, Writer
from hilrig.drivers.ft_sensor import FramerConfig, FramerStats, FtSample, KunweiFramer
from hilrig.drivers.ft_serial import FtSerial
from hilrig.drivers.gravity import GravityCompensator, ToolLoad, identify_tool_load
from hilrig.drivers.reconnect import Backoff

__all__ = [
    "Backoff",
    "Device",
    "FramerConfig",
    "FramerStats",
    "FtSample",
    "FtSerial",
    "GravityCompensator",
    "KunweiFramer",
    "LinkStatus",
    "Reader",
    "ToolLoad",
    "Writer",
    "identify_tool_load",
]
