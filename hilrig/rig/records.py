"""Fixed-layout rows the real-time loop hands to the recorder process, one numpy dtype each.

The loop writes rows into shared-memory rings (``rings.py``) and never blocks, allocates per
tick or pickles; the recorder process turns rows into recording samples. All times are host
monotonic ns (time.monotonic_ns); units are SI. Axis order of the controller arrays: the 3
Cartesian axes x, y, z (base frame, N and m) then joints 1..6 (N*m and rad).
"""

from __future__ import annotations

import numpy as np

from hilrig.recording.schema import AXIS_NAMES, JOINT_NAMES

__all__ = ["AXES", "AXIS_NAMES", "FT_DTYPE", "JOINTS", "JOINT_DTYPE", "JOINT_NAMES", "TICK_DTYPE"]

AXES = len(AXIS_NAMES)  # x, y, z, joint1..joint6: the names every topic uses
JOINTS = len(JOINT_NAMES)

# One wrist (or base) F/T sample as measured: sensor frame, N and N*m.
FT_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),  # host receive time
        ("seq", np.int64),  # the driver's frame counter
        ("wrench", np.float64, (6,)),  # Fx Fy Fz (N) Mx My Mz (N*m)
    ]
)

# One joint-state frame from the robot.
JOINT_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),  # host receive time
        ("device_t_ns", np.int64),  # the controller's clock
        ("seq", np.int64),  # the controller's frame sequence
        ("q", np.float64, (JOINTS,)),  # rad
        ("qd", np.float64, (JOINTS,)),  # rad/s
        ("tau", np.float64, (JOINTS,)),  # joint torque, N*m
    ]
)

# One control tick.
TICK_DTYPE = np.dtype(
    [
        ("t_ns", np.int64),  # the tick's start (after its deadline)
        ("tick", np.int64),
        ("force", np.float64, (AXES,)),  # the compensated controller input, N and N*m
        ("moment", np.float64, (3,)),  # the compensated wrist moment, base frame, N*m
        ("offset", np.float64, (AXES,)),  # e, m and rad
        ("offset_rate", np.float64, (AXES,)),  # e', m/s and rad/s
        ("damping", np.float64, (AXES,)),
        ("stiffness", np.float64, (AXES,)),
        ("chi", np.float64, (AXES,)),
        ("zeta", np.float64, (AXES,)),
        ("contact", np.int8, (AXES,)),  # ContactState codes
        ("desired_position", np.float64, (3,)),  # X_d, base frame, m
        ("desired_orientation", np.float64, (4,)),  # X_d, quaternion x y z w
        ("commanded_q", np.float64, (JOINTS,)),  # the joint targets sent, rad
        ("period_ns", np.int64),  # since the previous tick's start
        ("compute_ns", np.int64),  # work of this tick
        ("lateness_ns", np.int64),  # start - deadline
        ("overruns", np.int64),  # ticks so far whose work ran past the next deadline
        ("queue_drops", np.int64),  # rows the recorder rings refused so far
    ]
)
