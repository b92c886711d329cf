"""The loop's links as its events name them, and how long a failed command holds the robot.

The live loop (``hilrig.rig``) logs a link going stale or coming back as a fault event from
``SENSOR_LINK`` or ``ROBOT_LINK`` (detail ``STALE`` or ``FRESH_AGAIN``) on the tick it changed,
and a failed joint-target write from ``COMMAND_LINK``; its tick holds the robot while a link is
stale and for ``COMMAND_FAULT_HOLD_NS`` after a failed write. Closed-loop replay
(``hilrig.replay``) reads those events back to hold on the same ticks.
"""

from __future__ import annotations

SENSOR_LINK = "wrist F/T sensor"
ROBOT_LINK = "robot joint state"
COMMAND_LINK = "joint targets"
STALE = "stale or lost: the robot holds its pose until the data is fresh again"
FRESH_AGAIN = "data fresh again: tracking resumes"
COMMAND_FAULT_HOLD_NS = 50_000_000  # after a failed joint-target write, hold this long
