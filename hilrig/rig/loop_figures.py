"""What the loop reports: the status line's values while it runs, and its end-of-run figures.

:class:`LoopStatus` is a snapshot another thread takes for the status line
(:meth:`hilrig.rig.ControlLoop.status`); :class:`LoopSummary` counts ticks and holds the latency
histograms, and becomes the recording's ``outcome`` record (:meth:`LoopSummary.outcome`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hilrig.array_table import ArrayTable, view1
from hilrig.compiled import njit
from hilrig.recording import SessionOutcome
from hilrig.timing import LatencyHistogram, add_duration


@dataclass
class LoopStatus:
    """What the status line shows, taken from a running loop (``ControlLoop.status()``)."""

    ticks: int = 0
    lateness_us: float = 0.0
    force_n: float = 0.0
    offset_mm: float = 0.0
    contact: str = "free"
    holding: str = ""
    drops: int = 0
    stopped: bool = False


@dataclass
class LoopSummary:
    """End-of-run numbers: tick counts, lateness and latency histograms.

    ``io``: reading the three links and storing their rows, before a tick; ``compute``: the tick
    itself but for its send (the compiled tick, the events, the tick row written); ``send``: the
    Modbus request's send call (the OS's socket write). ``sensor_to_command``: F/T frame read ->
    the Modbus request with the targets computed from it sent; ``sensor_to_ack``: the same frame
    -> that request acknowledged by the robot.
    """

    ticks: int = 0
    missed_deadlines: int = 0  # ticks ending over a period after nominal, and merged frames
    fallback_ticks: int = 0  # ticks run on the deadline because no frame came
    merged_frames: int = 0  # frames read together with a newer one: no tick of their own
    hold_ticks: int = 0
    grid_shifts: int = 0  # times the nominal grid was found early and moved at once (.grid)
    start_ns: int = 0  # the loop's start (monotonic): the session's time 0
    ran_s: float = 0.0  # from the start to the last tick's nominal time
    lateness: LatencyHistogram = field(default_factory=LatencyHistogram)
    io: LatencyHistogram = field(default_factory=LatencyHistogram)
    compute: LatencyHistogram = field(default_factory=LatencyHistogram)
    send: LatencyHistogram = field(default_factory=LatencyHistogram)
    sensor_to_command: LatencyHistogram = field(default_factory=LatencyHistogram)
    sensor_to_ack: LatencyHistogram = field(default_factory=LatencyHistogram)

    def period_adder(self) -> Callable[[int, int, int, int], None]:
        """``add(io_ns, compute_ns, send_ns, lateness_ns)``: a tick's four durations into their
        histograms in one compiled call (:func:`add_period`, the histograms by address)."""
        arrays = [a for h in (self.io, self.compute, self.send, self.lateness) for a in h.arrays]
        return ArrayTable(arrays).bind(add_period, ((np.int64, 1),) * 8, last=(0, 0, 0, 0))

    def outcome(self, *, recorder_drops: int, ended_by: str) -> SessionOutcome:
        """These figures as the recording's ``outcome`` record."""
        return SessionOutcome(
            ticks=self.ticks,
            hold_ticks=self.hold_ticks,
            fallback_ticks=self.fallback_ticks,
            missed_deadlines=self.missed_deadlines,
            merged_frames=self.merged_frames,
            recorder_drops=recorder_drops,
            ended_by=ended_by,
            lateness_p50_us=self.lateness.quantile_us(0.5),
            lateness_p99_us=self.lateness.quantile_us(0.99),
            compute_p50_us=self.compute.quantile_us(0.5),
            compute_p99_us=self.compute.quantile_us(0.99),
            sensor_to_command_p50_us=self.sensor_to_command.quantile_us(0.5),
            sensor_to_command_p99_us=self.sensor_to_command.quantile_us(0.99),
        )


@njit(cache=True)
def add_period(
    table: NDArray[np.int64], io_ns: int, compute_ns: int, send_ns: int, lateness_ns: int
) -> None:
    """Each duration into its histogram: the table's rows are each one's counts and totals."""
    durations = (io_ns, compute_ns, send_ns, lateness_ns)
    for i in range(4):
        add_duration(view1(table, 2 * i, np.int64), view1(table, 2 * i + 1, np.int64), durations[i])
