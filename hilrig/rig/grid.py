"""The nominal grid of a sensor-triggered loop: when each tick's frame should have come.

The wrist sensor's frames carry no time of their own, so the grid is inferred from when they
arrive: one period per frame (frames read together advance it by as many), re-anchored to any
frame that comes early (the earliest arrivals show the sensor's schedule), and every
``window`` ticks moved later by the smallest lateness of the window (a sensor clock slower
than ours). A tick's lateness is its start minus its nominal time.

An early frame can be an odd one: on the slow machine, a frame read together with a late one came
0.8 ms ahead of its schedule, the next ones on it. The grid, anchored to it, made every later tick
look 0.8 ms late until its window ended: 539 and 989 ticks in one 60 s session, 2.5 % of its ticks,
which set its lateness p99 (842 us, against 277 us without them; docs/rig-timing.md). So when every
one of ``fast_window`` ticks in a row started more than ``fast_shift_ns`` after the grid, the grid
moves later by their smallest lateness at once. A real delay of every frame that long (more than
twice the loop's nudge, ``NUDGE_NS`` of :mod:`.loop`) would be hidden after ``fast_window`` ticks,
as the slow window hides one after ``window`` ticks.
"""

from __future__ import annotations

GRID_WINDOW = 1000  # ticks over which the grid follows a slow sensor clock
FAST_WINDOW = 50  # ticks in a row, each later than FAST_SHIFT_NS: the grid is early
FAST_SHIFT_NS = 400_000


class NominalGrid:
    """The grid of nominal tick times, anchored at ``start_ns`` (the loop's start: until a frame
    re-anchors it, a silent sensor's fallback ticks fall on it)."""

    def __init__(
        self,
        period_ns: int,
        start_ns: int,
        *,
        window: int = GRID_WINDOW,
        fast_window: int = FAST_WINDOW,
        fast_shift_ns: int = FAST_SHIFT_NS,
    ) -> None:
        self.period_ns = period_ns
        self.nominal_ns = start_ns  # the last tick's nominal time
        self._window, self._fast_window, self._fast_shift_ns = window, fast_window, fast_shift_ns
        self._placed = 0
        self._window_min: int | None = None
        self._run = 0  # ticks in a row later than fast_shift_ns
        self._run_min = 0  # the smallest lateness of that run
        self.fast_shifts = 0  # times the grid was found wrong and moved at once

    def place(self, now_ns: int, frames: int) -> int:
        """The nominal time of a tick started at ``now_ns`` on ``frames`` new frames (0: a
        fallback tick, on the deadline one period after the last)."""
        expected = self.nominal_ns + self.period_ns * max(frames, 1)
        nominal = min(expected, now_ns)  # an early frame re-anchors the grid
        lateness = now_ns - nominal
        window_min = lateness if self._window_min is None else min(self._window_min, lateness)
        if lateness > self._fast_shift_ns:
            self._run_min = min(self._run_min, lateness) if self._run else lateness
            self._run += 1
        else:
            self._run = 0
        self._placed += 1
        self.nominal_ns = nominal
        if self._placed % self._window == 0:
            self.nominal_ns += window_min  # the window's best arrival is on time
            self._window_min, self._run = None, 0
        elif self._run == self._fast_window:  # every tick that late: the grid is early
            self.nominal_ns += self._run_min
            self._window_min, self._run = None, 0  # the window's values were against it
            self.fast_shifts += 1
        else:
            self._window_min = window_min
        return nominal
