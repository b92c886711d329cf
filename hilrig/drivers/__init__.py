"""Device protocols: the wrist/base F/T sensors (serial), robot joint state (TCP), joint targets.

Every driver follows :mod:`hilrig.drivers.base`: ``connect()``/``close()`` (or ``with``), a reader
thread behind a non-blocking ``latest()``, and a :class:`~hilrig.drivers.base.LinkStatus`.
Wire formats are pure modules (no I/O) so they can be fuzzed and replayed; the emulated rig in
:mod:`hilrig.drivers.emulated` speaks the same bytes over a pty and loopback sockets.
"""

from hilrig.drivers.base import Device, LinkStatus, Reader, Writer
from hilrig.drivers.ft_sensor import FramerConfig, FramerStats, FtSample, KunweiFramer
from hilrig.drivers.ft_serial import FtSerial
from hilrig.drivers.gravity import GravityCompensator, ToolLoad, identify_tool_load

__all__ = [
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
