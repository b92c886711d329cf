"""The force trace every replay runs on: uniformly sampled force/torque, one row per tick."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import ReplayError
from hilrig.recording import SessionInfo


@dataclass(frozen=True)
class ForceTrace:
    """A uniformly sampled force/torque trace, one row per controller tick.

    ``force`` (T, A) in N (x, y, z) and N*m (joint1..joint6), columns in ``axis_names`` order;
    ``t_s`` (T,) each tick's start from the start of the input, s; ``dt_s`` the controller
    period, s. ``t0_ns`` is the first tick's MCAP log time (ns since the Unix epoch) and
    ``session`` the recording's session record, for inputs that are recordings. ``notes`` are
    one-line remarks on how the input was read (resampling, skipped data).
    """

    t_s: NDArray[np.float64]
    force: NDArray[np.float64]
    axis_names: tuple[str, ...]
    source: str
    dt_s: float
    t0_ns: int | None = None
    session: SessionInfo | None = None
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.force.ndim != 2 or self.force.shape != (len(self.t_s), len(self.axis_names)):
            raise ReplayError(
                f"{self.source}: force has shape {self.force.shape}, expected "
                f"({len(self.t_s)}, {len(self.axis_names)})"
            )
        if len(self.t_s) < 1 or not (np.isfinite(self.dt_s) and self.dt_s > 0):
            raise ReplayError(f"{self.source}: no ticks, or a period of {self.dt_s} s")

    @property
    def ticks(self) -> int:
        return len(self.t_s)

    @property
    def duration_s(self) -> float:
        """Ticks times the period, s."""
        return self.ticks * self.dt_s

    @property
    def columns(self) -> dict[str, NDArray[np.float64]]:
        """``{axis name: force column}`` (views, not copies)."""
        return {name: self.force[:, i] for i, name in enumerate(self.axis_names)}
