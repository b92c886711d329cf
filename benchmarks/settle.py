"""Wait for a quiet machine before a timing suite.

A suite that fills and frees gigabytes (control, recording) leaves these VMs slow to wake for a
while after it: by hand on 2026-12-06 (a Firecracker VM on AMD EPYC), a bare thread's 1 kHz
wake-ups were over a period late 3.34 % of the time right after the control suite and 0.015 %
about 80 s later, in the same process (0.0 % with the machine suite run alone). A timing suite
measured in that wake would report the previous suite's after-effect, not the loop's, so the
suites that time the machine, the links and the sessions (machine, drivers, rig, session) first
wait until a bare thread's wake-ups in a window are none over a period late (at most ``MAX_S``),
and report how long that took. (The drivers suite's F/T stream, run right after the control
suite on 2026-12-06 06:00, once got 883 Hz with a 293 ms gap; a minute later 1000 Hz.)
"""

from __future__ import annotations

import gc
import time

import numpy as np

from benchmarks.harness import Result
from hilrig.machine.floor import PERIOD_NS, wake_ups

WINDOW_S = 2.0  # one look: a bare thread's 1 kHz wake-ups for this long
MAX_S = 180.0  # then the suite runs anyway, and the row says the machine was not quiet


def settle(suite: str) -> Result:
    """Wait until a window of wake-ups has none over a period late, or ``MAX_S``; the wait."""
    gc.collect()
    started = time.monotonic()
    windows = 0
    while True:
        late = int(np.count_nonzero(wake_ups(WINDOW_S).late_ns > PERIOD_NS))
        windows += 1
        waited_s = time.monotonic() - started
        if late == 0 or waited_s >= MAX_S:
            break
    detail = {"windows": windows, "window_s": WINDOW_S, "late_in_last_window": late}
    return Result(suite, "waited for a quiet machine before it", waited_s, "s", detail=detail)
