"""The live loop's tick: its inputs' freshness and what changed since the last tick, judged in
the same compiled call as the tick itself (:func:`loop_entry`).

The loop's tick used to judge in Python, every tick, whether the sensor's and the robot's newest
samples were fresh, which command flags held, and then ask its event detector whether a link's
state or the clamp's flags had changed. :func:`loop_entry` reads the newest rows' receive times
in place, takes the flags from them and the loop's ``words`` (:data:`STALE_NS` and
:data:`ROBOT_STALE_NS`: the sensor's and the robot's staleness limits, the robot's following
its own state rate; :data:`HOLD_UNTIL_NS`: no command before this time, after a failed write), runs
:func:`~hilrig.tick.step_kernel.tick_kernel` and adds result bits for what changed: the loop
leaves Python's event detector only for the ticks with something to report (:data:`REPORT`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import Layout, view1
from hilrig.compiled import njit
from hilrig.drivers.ft.wire import SAMPLE_DTYPE
from hilrig.drivers.robot_state.wire import STATE_DTYPE
from hilrig.tick.step_kernel import (
    COMMAND_OK,
    CONTACT_CHANGED,
    ROBOT_OK,
    SENSOR_OK,
    STOP_NOW,
    STOPPED,
    TICK_LAYOUT,
    tick_entry,
)

# Entries of the loop's int64 words: its settings, then what the last tick saw
STALE_NS, HOLD_UNTIL_NS, SENSOR_WAS_OK, ROBOT_WAS_OK, CLAMP_WAS, ROBOT_STALE_NS = range(6)
LOOP_WORDS = 6
# Result bits beyond the tick kernel's (which end at 1 << 11)
SENSOR_CHANGED, ROBOT_CHANGED, CLAMP_CHANGED = 1 << 12, 1 << 13, 1 << 14
SENSOR_IS_OK, ROBOT_IS_OK, IS_STOPPED = 1 << 15, 1 << 16, 1 << 17
REPORT = SENSOR_CHANGED | ROBOT_CHANGED | CLAMP_CHANGED | CONTACT_CHANGED | STOP_NOW

# loop_entry's table: the tick's arrays, then the newest F/T sample, joint state and the words
LOOP_LAYOUT: Layout = (*TICK_LAYOUT, (SAMPLE_DTYPE, 1), (STATE_DTYPE, 1), (np.int64, 1))
_NEWEST_SAMPLE = len(TICK_LAYOUT)
COUNTERS = _NEWEST_SAMPLE - 1  # the tick's counters: its last array


def loop_words(stale_ns: int, robot_stale_ns: int | None = None) -> NDArray[np.int64]:
    """The words of a loop about to start: both links taken as fresh until seen otherwise (as
    the event detector takes them), no clamp, commands allowed. The robot's limit is the
    sensor's unless given."""
    words = np.zeros(LOOP_WORDS, dtype=np.int64)
    words[STALE_NS] = stale_ns
    words[ROBOT_STALE_NS] = stale_ns if robot_stale_ns is None else robot_stale_ns
    words[SENSOR_WAS_OK] = words[ROBOT_WAS_OK] = 1
    return words


@njit(cache=True)
def loop_entry(table: NDArray[np.int64], start_ns: int) -> int:
    """The tick started at ``start_ns`` on the arrays of ``table`` (LOOP_LAYOUT): the kernel's
    result, with the bits of what changed and of the links' and the stop's state."""
    sample = view1(table, _NEWEST_SAMPLE, SAMPLE_DTYPE)
    state = view1(table, _NEWEST_SAMPLE + 1, STATE_DTYPE)
    words = view1(table, _NEWEST_SAMPLE + 2, np.int64)
    sample_t, state_t = sample[0].t_ns, state[0].t_ns
    sensor_ok = sample_t > 0 and start_ns - sample_t <= words[STALE_NS]  # 0: nothing yet
    robot_ok = state_t > 0 and start_ns - state_t <= words[ROBOT_STALE_NS]
    flags = (SENSOR_OK if sensor_ok else 0) | (ROBOT_OK if robot_ok else 0)
    if start_ns >= words[HOLD_UNTIL_NS]:
        flags |= COMMAND_OK
    result: int = tick_entry(table, flags)  # the table's first rows are the tick's
    if sensor_ok != (words[SENSOR_WAS_OK] != 0):
        words[SENSOR_WAS_OK] = 1 if sensor_ok else 0
        result |= SENSOR_CHANGED
    if robot_ok != (words[ROBOT_WAS_OK] != 0):
        words[ROBOT_WAS_OK] = 1 if robot_ok else 0
        result |= ROBOT_CHANGED
    clamp = result & 0xFF
    if clamp != words[CLAMP_WAS]:
        words[CLAMP_WAS] = clamp
        result |= CLAMP_CHANGED
    if sensor_ok:
        result |= SENSOR_IS_OK
    if robot_ok:
        result |= ROBOT_IS_OK
    if view1(table, COUNTERS, np.int64)[STOPPED] != 0:
        result |= IS_STOPPED
    return result
