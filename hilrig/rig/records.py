"""Fixed-layout rows the real-time loop hands to the recorder process, one numpy dtype each.

The loop writes rows into shared-memory rings (``rings.py``) and never blocks, allocates per
tick or pickles; the recorder process turns rows into recording samples. All times are host
monotonic ns (time.monotonic_ns); units are SI. Axis order of the controller arrays: the 3
Cartesian axes x, y, z (base frame, N and m) then joints 1..6 (N*m and rad).
"""

from __future__ import annotations

import numpy as np

from hilrig.drivers.ft.wire import SAMPLE_DTYPE
from hilrig.drivers.robot_state.wire import STATE_DTYPE
from hilrig.recording.schema import AXES, AXIS_NAMES, JOINT_NAMES
from hilrig.tick.row import TICK_DTYPE

__all__ = [
    "AXES",
    "AXIS_BYTES",
    "AXIS_NAMES",
    "DETAIL_BYTES",
    "EVENT_DTYPE",
    "FT_DTYPE",
    "JOINTS",
    "JOINT_DTYPE",
    "JOINT_NAMES",
    "SERVO_DTYPE",
    "SOURCE_BYTES",
    "TICK_DTYPE",
    "fitted",
]

JOINTS = len(JOINT_NAMES)

# One wrist (or base) F/T sample as its driver frames it: receive time, frame counter, wrench as
# measured (sensor frame, N and N*m)
FT_DTYPE = SAMPLE_DTYPE

# One joint-state frame from the robot, as its driver decodes it (host receive time, the
# controller's clock and sequence, q rad, qd rad/s, tau N*m, status bits; the status is not
# recorded)
JOINT_DTYPE = STATE_DTYPE

# One servo call to the robot (the ARCS link's servoJoint): when it left and returned, the sensor
# sample its targets answer (0: none), the controller's answer (0: accepted), the loop's mode,
# the targets sent (rad)
SERVO_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),
        ("done_ns", np.int64),
        ("source_ns", np.int64),
        ("code", np.int64),
        ("mode", np.int64),
        ("q", np.float64, (JOINTS,)),
    ]
)

# One event (hilrig.recording.EventRecord): host time, value (NaN when none), kind code, then
# source, axis and detail as UTF-8, each cut to its field (CUT marks a cut: see fitted)
SOURCE_BYTES, AXIS_BYTES, DETAIL_BYTES = 48, 24, 448
EVENT_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),
        ("value", "<f8"),
        ("kind", "u1"),
        ("source", f"S{SOURCE_BYTES}"),
        ("axis", f"S{AXIS_BYTES}"),
        ("detail", f"S{DETAIL_BYTES}"),
    ]
)
CUT = b" [cut]"


def fitted(text: str, size: int) -> bytes:
    """``text`` as UTF-8 in at most ``size`` bytes: whole, or cut at a character's end and
    marked by CUT (an event's text is never cut silently)."""
    data = text.encode()
    if len(data) <= size:
        return data
    kept = data[: size - len(CUT)].decode(errors="ignore").encode()
    return kept + CUT
