"""A recorded force/torque trace played into the live loop as a virtual collision.

The trace is added to the measured, compensated controller input on every fresh tick, so the
robot yields as if the recorded person pushed it again, on the emulated rig or on the real one.
Because the addition happens before the controller, the session's ``/controller/input`` holds
exactly what the controller saw, and the new recording replays as exactly as any other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import HilrigError
from hilrig.rig.records import AXES, AXIS_NAMES


@dataclass(frozen=True)
class VirtualInput:
    """``force`` (T, 9): x, y, z in N (base frame) then joint1..6 in N*m, one row per ``dt_s``;
    row 0 plays ``delay_s`` after the loop's first tick, each row held for ``dt_s``."""

    force: NDArray[np.float64]
    dt_s: float
    delay_s: float = 1.0

    def __post_init__(self) -> None:
        if self.force.ndim != 2 or self.force.shape[1] != AXES:
            raise HilrigError(f"a virtual input needs (T, {AXES}) values, got {self.force.shape}")
        if not np.isfinite(self.force).all():
            raise HilrigError("a virtual input must be finite everywhere")
        if not (self.dt_s > 0 and self.delay_s >= 0):
            raise HilrigError(f"virtual input: dt_s {self.dt_s} must be > 0, delay_s >= 0")

    @classmethod
    def from_columns(
        cls,
        t_s: NDArray[np.float64],
        columns: dict[str, NDArray[np.float64]],
        *,
        start_s: float = 0.0,
        duration_s: float | None = None,
        delay_s: float = 1.0,
    ) -> VirtualInput:
        """From uniformly sampled columns named after AXIS_NAMES (missing axes are zero),
        cut to [start_s, start_s + duration_s) of the trace's own time ``t_s`` (s)."""
        unknown = sorted(set(columns) - set(AXIS_NAMES))
        if unknown:
            raise HilrigError(f"virtual input: unknown axes {unknown}; known: {AXIS_NAMES}")
        if len(t_s) < 2:
            raise HilrigError("virtual input: the trace needs at least two samples")
        end_s = np.inf if duration_s is None else start_s + duration_s
        keep = (t_s >= t_s[0] + start_s) & (t_s < t_s[0] + end_s)
        if not keep.any():
            raise HilrigError(f"virtual input: nothing in [{start_s}, {end_s}) s of the trace")
        force = np.zeros((int(keep.sum()), AXES))
        for axis, values in columns.items():
            force[:, AXIS_NAMES.index(axis)] = values[keep]
        dt_s = float(np.median(np.diff(t_s)))
        return cls(force, dt_s, delay_s)

    @property
    def duration_s(self) -> float:
        return float(self.force.shape[0] * self.dt_s)

    def add_to(self, t_s: float, out: NDArray[np.float64]) -> bool:
        """Add the row playing at loop time ``t_s`` (s) to ``out`` (9,); False outside it."""
        n = int((t_s - self.delay_s) // self.dt_s)
        if 0 <= n < self.force.shape[0]:
            np.add(out, self.force[n], out=out)
            return True
        return False
