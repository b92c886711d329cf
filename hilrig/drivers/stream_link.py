"""What the two streaming drivers share: a poll that never raises, returning rows of a fixed
dtype, the newest row, and the link's counts.

:class:`StreamLink` is the bookkeeping of :class:`~hilrig.drivers.ft.link.FtSerial` and
:class:`~hilrig.drivers.robot_state.link.RobotStateClient`, around their own ``_pump`` (open or
reopen the link when due, read, decode; raise on a lost link) and ``_drop`` (close it):
:meth:`~StreamLink.poll` counts and keeps each error, drops the link and backs off; the rows
read while connecting come first in the next poll; the newest row and its receive time, the
samples, their rate and the stalls, reconnects and errors make the :class:`LinkStatus`.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus, RateMeter, error_text
from hilrig.drivers.reconnect import Backoff

Rows = NDArray[np.void]


class StreamLink(ABC):
    """A polled stream's rows and counts; subclasses read the link (``_pump``, ``_drop``)."""

    def __init__(self, rows: Rows, newest: Rows, backoff: Backoff) -> None:
        self.rows = rows
        """The decoder's rows: a poll's rows are their first ``n`` (but after a connect, when
        the rows read while connecting come first)."""
        self.newest = newest
        """The newest row, kept current in place by the decoder (its fields are views); it
        means something once :attr:`latest_t_ns` >= 0."""
        self._backoff = backoff
        self._none: Rows = np.zeros(0, dtype=newest.dtype)
        self._unreturned = self._none  # read while connecting, returned by the next poll
        self._latest_t_ns = -1
        self._samples = 0
        self._rate = RateMeter()
        self.stalls = 0
        self.reconnects = 0
        self.errors = 0
        self.last_error = ""

    @abstractmethod
    def _pump(self, now_ns: int) -> Rows:
        """Open the link when due, read and decode; the rows read (raises on a lost link)."""

    @abstractmethod
    def _drop(self) -> None:
        """Close the link (poll reopens it when due)."""

    def poll(self, now_ns: int) -> Rows:
        """The rows read now (stamped ``now_ns``), oldest first, as rows the next poll reuses;
        never blocks, never raises."""
        try:
            rows = self._pump(now_ns)
        except Exception as err:  # whatever happens (even a bug), the caller's loop carries on
            self.errors += 1
            self.last_error = error_text(err)
            self._drop()
            self._backoff.failed(now_ns)
            rows = self._none
        if len(self._unreturned):
            rows, self._unreturned = np.concatenate((self._unreturned, rows)), self._none
        return rows

    def latest(self) -> np.void | None:
        """The newest row (kept current in place: copy to keep it); None before the first."""
        return None if self._latest_t_ns < 0 else self.newest[0]

    @property
    def latest_t_ns(self) -> int:
        """The newest row's receive time (monotonic ns); -1 before the first."""
        return self._latest_t_ns

    def _received(self, now_ns: int, n: int) -> None:
        """``n`` rows (> 0) were read at ``now_ns``."""
        self._latest_t_ns = now_ns
        self._samples += n
        self._rate.update(now_ns, self._samples)

    def _link_status(self, endpoint: str, connected: bool) -> LinkStatus:
        age_ns = None if self._latest_t_ns < 0 else time.monotonic_ns() - self._latest_t_ns
        return LinkStatus(
            endpoint=endpoint,
            connected=connected,
            samples=self._samples,
            rate_hz=self._rate.rate_hz(age_ns),
            age_ns=age_ns,
            stalls=self.stalls,
            reconnects=self.reconnects,
            errors=self.errors,
            last_error=self.last_error,
        )
