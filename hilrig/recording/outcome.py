"""How a recorded session went: the loop's end figures, as the ``outcome`` metadata record.

The recorder writes it last, when the session ends cleanly (``hilrig record`` hands it over with
the stop): ticks, hold ticks (the robot held its pose: stale input, a command fault or a
protective stop), fallback ticks (no sensor frame: ticked on the deadline), missed deadlines,
frames merged with a newer one, rows the recorder's rings refused, how the session ended
(``ended_by``: :data:`DURATION_REACHED`, a stop by the operator, a fault; "" in files of older
hilrig, read as :data:`DURATION_REACHED`) and the loop's timing (lateness, compute per tick and
sensor-to-command, p50 and p99 in us; ``nan`` where nothing was measured). A file without it
did not end cleanly (the recorder or the loop died) or was written by an older hilrig;
``hilrig info`` says so. Values are text, as MCAP metadata are: integers in decimal, times
with 0.1 us.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

from hilrig.errors import RecordingError

OUTCOME_METADATA = "outcome"
#: ``ended_by`` of a session that ran its course.
DURATION_REACHED = "duration reached"
#: ``ended_by`` of a session stopped from outside: SIGINT (Ctrl-C), SIGTERM, or by its caller.
INTERRUPTED = "interrupted by the operator (SIGINT)"
TERMINATED = "terminated (SIGTERM)"
STOPPED = "stopped by its caller"


def ran_its_course(ended_by: str) -> bool:
    """Whether ``ended_by`` says the session ran its whole duration ("": an older hilrig's)."""
    return ended_by in ("", DURATION_REACHED)


def stopped_from_outside(ended_by: str) -> bool:
    """Whether ``ended_by`` says the session was stopped before its time, not by a fault."""
    return ended_by in (INTERRUPTED, TERMINATED, STOPPED)


@dataclass(frozen=True)
class SessionOutcome:
    """The loop's end figures of one session (see the module's docstring)."""

    ticks: int
    hold_ticks: int
    fallback_ticks: int
    missed_deadlines: int
    merged_frames: int
    recorder_drops: int
    ended_by: str
    lateness_p50_us: float
    lateness_p99_us: float
    compute_p50_us: float
    compute_p99_us: float
    sensor_to_command_p50_us: float
    sensor_to_command_p99_us: float

    def to_metadata(self) -> dict[str, str]:
        """The record's values (text)."""
        values: dict[str, str] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            values[f.name] = f"{value:.1f}" if isinstance(value, float) else str(value)
        return values

    @classmethod
    def from_metadata(cls, values: Mapping[str, str]) -> SessionOutcome:
        """Parse the record; RecordingError (one line) naming the first missing or bad value."""
        parsed: dict[str, int | float | str] = {}
        for f in fields(cls):
            text = values.get(f.name)
            if text is None:
                raise RecordingError(f"metadata record {OUTCOME_METADATA!r}: no {f.name}")
            if f.type == "str":
                parsed[f.name] = text
                continue
            try:
                number = int(text) if f.type == "int" else float(text)
            except ValueError:
                raise RecordingError(
                    f"metadata record {OUTCOME_METADATA!r}: {f.name} {text!r} is not a number"
                ) from None
            if number < 0:  # NaN (nothing measured, e.g. no fresh command) passes
                raise RecordingError(
                    f"metadata record {OUTCOME_METADATA!r}: {f.name} {text!r} is not >= 0"
                )
            parsed[f.name] = number
        return cls(**parsed)  # type: ignore[arg-type]

    @property
    def ended(self) -> str:
        """How the session ended: ``ended_by``, an older hilrig's "" as :data:`DURATION_REACHED`."""
        return self.ended_by or DURATION_REACHED

    @property
    def ended_early(self) -> bool:
        """Whether it ended before its time (stopped from outside, or a fault)."""
        return not ran_its_course(self.ended_by)

    @property
    def missed_pct(self) -> float:
        """Missed deadlines in % of ticks (0 without ticks)."""
        return 100.0 * self.missed_deadlines / self.ticks if self.ticks else 0.0
