"""Fixed-layout rows the real-time loop hands to the recorder process, one numpy dtype each.

The loop writes rows into shared-memory rings (``rings.py``) and never blocks, allocates per
tick or pickles; the recorder process turns rows into recording samples. All times are host
monotonic ns (time.monotonic_ns); units are SI. Axis order of the controller arrays: the 3
Cartesian axes x, y, z (base frame, N and m) then joints 1..6 (N*m and rad).
"""

from __future__ import annotations

from hilrig.drivers.ft.wire import SAMPLE_DTYPE
from hilrig.drivers.robot_state.wire import STATE_DTYPE
from hilrig.recording.schema import AXES, AXIS_NAMES, JOINT_NAMES
from hilrig.tick.row import TICK_DTYPE

__all__ = ["AXES", "AXIS_NAMES", "FT_DTYPE", "JOINTS", "JOINT_DTYPE", "JOINT_NAMES", "TICK_DTYPE"]

JOINTS = len(JOINT_NAMES)

# One wrist (or base) F/T sample as its driver frames it: receive time, frame counter, wrench as
# measured (sensor frame, N and N*m)
FT_DTYPE = SAMPLE_DTYPE

# One joint-state frame from the robot, as its driver decodes it (host receive time, the
# controller's clock and sequence, q rad, qd rad/s, tau N*m, status bits; the status is not
# recorded)
JOINT_DTYPE = STATE_DTYPE
