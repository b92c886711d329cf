"""The tick's row: the compiled tick's results written into the recorder ring's slot in place.

The row's layout is ``TICK_DTYPE`` (``hilrig/rig/records.py``, from the recording schema); the
loop calls :func:`put_tick_row` through :meth:`hilrig.tick.kernel.CompiledTick.row_writer`
(bound: no dispatch), which reserves the ring's slot, fills it and publishes it in one call.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.recording.schema import AXES
from hilrig.ring_kernels import DROPPED_AT, publish, reserve_slot
from hilrig.robot import JOINTS

# The compiled tick's ``work`` vector (float64): offsets of its parts.
W_FRESH, W_FORCE, W_WRENCH, W_MOMENT, W_GRAVITY_S = 0, 9, 18, 24, 27
W_Q_IK, W_TARGET, W_Q_CMD = 30, 36, 42
WORK_SIZE = 48


@njit(cache=True)
def put_tick_row(
    rows: NDArray[np.void],
    header: NDArray[np.int64],
    drops_from: tuple[NDArray[np.int64], ...],
    work: NDArray[np.float64],
    results: NDArray[np.float64],
    contact: NDArray[np.int8],
    mass: NDArray[np.float64],
    position_d: NDArray[np.float64],
    orientation_d: NDArray[np.float64],
    t_ns: int,
    tick: int,
    period_ns: int,
    compute_ns: int,
    lateness_ns: int,
    overruns: int,
    other_drops: int,
) -> bool:
    """The tick's row (TICK_DTYPE) into the next free slot of the ring (``rows``, ``header``),
    published; False if the ring was full (a drop, counted).

    ``results`` is the controller's ``out`` (offset, rate, damping, stiffness rows of one tick);
    the timing fields come as plain ints (a numpy store from Python costs microseconds). The
    row's ``queue_drops`` are the drops counted in the headers ``drops_from`` (this ring's among
    them) plus ``other_drops``.
    """
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
    row.queue_drops = other_drops
    for words in drops_from:
        row.queue_drops += words[DROPPED_AT]
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
