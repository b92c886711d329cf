"""When to try reopening a lost link: exponential backoff between bounds, reset on success.

Shared by every polled driver. It only answers "is an attempt due at ``now_ns``?": the driver
makes the (non-blocking) attempt itself from its ``poll``, so no thread and no sleep is needed.
A retry library such as tenacity wraps a blocking call in a sleeping loop, which is what the
polled drivers must not do; the policy itself is a few lines.
"""

from __future__ import annotations

from hilrig.errors import ParameterError


class Backoff:
    """Attempt times after failures: ``min_s``, then doubling up to ``max_s``; reset on success."""

    def __init__(self, bounds_s: tuple[float, float] = (0.01, 1.0), *, factor: float = 2.0) -> None:
        min_s, max_s = bounds_s
        if not 0.0 < min_s <= max_s or factor < 1.0:
            raise ParameterError(f"backoff needs 0 < min <= max and factor >= 1, got {bounds_s}")
        self._min_ns = round(min_s * 1e9)
        self._max_ns = round(max_s * 1e9)
        self._factor = factor
        self._delay_ns = self._min_ns
        self.next_attempt_ns = 0  # 0: an attempt may be made now

    @property
    def delay_s(self) -> float:
        """The wait that the next failure will schedule."""
        return self._delay_ns / 1e9

    def due(self, now_ns: int) -> bool:
        """True when an attempt may be made at ``now_ns``."""
        return now_ns >= self.next_attempt_ns

    def failed(self, now_ns: int) -> None:
        """A link was lost or an attempt failed at ``now_ns``: wait, then wait longer next time."""
        self.next_attempt_ns = now_ns + self._delay_ns
        self._delay_ns = min(round(self._delay_ns * self._factor), self._max_ns)

    def succeeded(self) -> None:
        """The link is up: the next loss waits ``min_s`` again."""
        self._delay_ns = self._min_ns
        self.next_attempt_ns = 0
