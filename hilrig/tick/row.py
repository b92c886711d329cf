"""The tick's row: the compiled tick's results written into the recorder ring's slot in place.

The row's layout is :data:`TICK_DTYPE` (the recording schema's ``TICK_FIELDS``, in order); the
loop calls :func:`put_tick_row` through :meth:`hilrig.tick.kernel.CompiledTick.row_writer`
(its arrays by address), which reserves the ring's slot, fills it and publishes it in one call.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import Layout, view1, view2, view3
from hilrig.compiled import njit
from hilrig.recording.schema import AXES, TICK_FIELDS
from hilrig.ring_kernels import DROPPED_AT, publish, reserve_slot
from hilrig.robot import JOINTS

# The compiled tick's ``work`` vector (float64): offsets of its parts.
W_FRESH, W_FORCE, W_WRENCH, W_MOMENT, W_GRAVITY_S = 0, 9, 18, 24, 27
W_Q_IK, W_TARGET, W_Q_CMD = 30, 36, 42
WORK_SIZE = 48

# One control tick: the fields of TICK_FIELDS (names, units, which ControllerState array each
# fills), in that order.
TICK_DTYPE = np.dtype(
    [(f.name, f.kind, (f.size,)) if f.size else (f.name, f.kind) for f in TICK_FIELDS]
)


# (dtype, dimensions) of put_tick_row's arrays; then the headers whose drops the row adds up
ROW_LAYOUT: Layout = (
    (TICK_DTYPE, 1),  # the ring's rows
    (np.int64, 1),  # its header
    (np.float64, 1),  # the tick's work
    (np.float64, 3),  # the controller's out
    (np.int8, 2),  # its contact codes
    *((np.float64, 1),) * 3,  # its masses, the desired position and orientation
)
DROPS_FROM = len(ROW_LAYOUT)  # the table's first header whose drops count


@njit(cache=True)
def put_tick_row(
    table: NDArray[np.int64],
    t_ns: int,
    tick: int,
    period_ns: int,
    compute_ns: int,
    lateness_ns: int,
    overruns: int,
) -> bool:
    """The tick's row (TICK_DTYPE) into the next free slot of the ring, published; False if the
    ring was full (a drop, counted). The arrays are ``table``'s (ROW_LAYOUT: the ring's rows and
    header, the tick's work, the controller's ``out`` (offset, rate, damping, stiffness rows of
    one tick), contact codes and masses, the desired position and orientation; then headers).

    The timing fields come as plain ints (a numpy store from Python costs microseconds); the
    row's ``queue_drops`` are the drops counted in the table's headers (the ring's own among
    them).
    """
    rows, header = view1(table, 0, TICK_DTYPE), view1(table, 1, np.int64)
    work, results = view1(table, 2, np.float64), view3(table, 3, np.float64)
    contact, mass = view2(table, 4, np.int8), view1(table, 5, np.float64)
    position_d, orientation_d = view1(table, 6, np.float64), view1(table, 7, np.float64)
    queue_drops = 0
    for i in range(DROPS_FROM, table.shape[0]):
        queue_drops += view1(table, i, np.int64)[DROPPED_AT]
    slot = reserve_slot(header, rows.shape[0])
    if slot < 0:
        return False
    row = rows[slot]
    row.t_ns = t_ns
    row.tick = tick
    row.period_ns = period_ns
    row.compute_ns = compute_ns
    row.lateness_ns = lateness_ns
    row.overruns = overruns
    row.queue_drops = queue_drops
    for i in range(AXES):
        f = work[W_FORCE + i]
        b = results[2, 0, i]
        k = results[3, 0, i]
        row.force[i] = f
        row.offset[i] = results[0, 0, i]
        row.offset_rate[i] = results[1, 0, i]
        row.damping[i] = b
        row.stiffness[i] = k
        row.chi[i] = math.tanh(f * f)
        row.zeta[i] = b / math.sqrt(mass[i] * k) * 0.5
        row.contact[i] = contact[0, i]
    for r in range(3):
        row.moment[r] = work[W_MOMENT + r]
        row.desired_position[r] = position_d[r]
    for r in range(4):
        row.desired_orientation[r] = orientation_d[r]
    for j in range(JOINTS):
        row.commanded_q[j] = work[W_Q_CMD + j]
    publish(header, 1)
    return True
