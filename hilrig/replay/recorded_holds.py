"""The live loop's link flags on each recorded tick, read back from the recording's events.

A session's loop holds the robot while the sensor's or the robot's data is stale, and for
``COMMAND_FAULT_HOLD_NS`` after a failed joint-target write (:mod:`hilrig.tick.links`); it logs
each change as a fault event at the start of the tick it happened on. Closed-loop replay gives
its tick the same flags on the same ticks, so a recorded hold is replayed as a hold under every
controller: the silence that made the loop hold would have come under any of them. A recording
without these events (another writer's, or one whose recorder dropped them) replays as if its
links had never failed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.recording.samples import EventKind
from hilrig.tick.links import COMMAND_FAULT_HOLD_NS, COMMAND_LINK, ROBOT_LINK, SENSOR_LINK, STALE
from hilrig.tick.step_kernel import COMMAND_OK, ROBOT_OK, SENSOR_OK

ALL_OK = SENSOR_OK | ROBOT_OK | COMMAND_OK
_LINK_BITS = {SENSOR_LINK: SENSOR_OK, ROBOT_LINK: ROBOT_OK}


def recorded_flags(tick_ns: NDArray[np.int64], events: pd.DataFrame | None) -> NDArray[np.int64]:
    """Per tick (``tick_ns``: the ticks' start times, ascending), the flags the live loop gave
    its tick: ``SENSOR_OK | ROBOT_OK | COMMAND_OK`` but for a link stale from the tick of its
    stale event up to the tick of its fresh-again one, and commands held from a failed write's
    tick for ``COMMAND_FAULT_HOLD_NS``. ``events``: the ``/events`` frame (index: log time)."""
    flags = np.full(len(tick_ns), ALL_OK, dtype=np.int64)
    if events is None or len(events) == 0:
        return flags
    faults = events[events["kind"].to_numpy() == int(EventKind.FAULT)].sort_index(kind="stable")
    times = faults.index.to_numpy(np.int64)
    first = np.searchsorted(tick_ns, times, side="left")
    stale_from: dict[str, int] = {}
    for at_ns, tick, source, detail in zip(
        times, first, faults["source"], faults["detail"], strict=True
    ):
        if source == COMMAND_LINK:
            until = np.searchsorted(tick_ns, at_ns + COMMAND_FAULT_HOLD_NS, side="left")
            flags[tick:until] &= ~COMMAND_OK
        elif source in _LINK_BITS:
            if detail == STALE:
                stale_from.setdefault(source, int(tick))
            elif source in stale_from:
                flags[stale_from.pop(source) : tick] &= ~_LINK_BITS[source]
    for source, tick in stale_from.items():  # stale to the session's end
        flags[tick:] &= ~_LINK_BITS[source]
    return flags
