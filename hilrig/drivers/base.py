"""The shape every device driver follows: connect, poll from the caller's loop, close.

Like LeRobot's device classes, but structural: a driver satisfies :class:`Reader` or
:class:`Writer` by having the methods, and may subclass them to inherit ``__enter__`` (connect)
and ``__exit__`` (close). Drivers run no thread of their own: the caller's loop selects on every
``fileno()`` (-1 while a link is down), then calls ``poll(now_ns)``, which does all the I/O
without blocking, never raises (errors are counted in :class:`LinkStatus`) and reopens a lost
link with backoff (:mod:`hilrig.drivers.reconnect`). Only ``connect()`` may block.
"""

from __future__ import annotations

import select
import time
from collections.abc import Collection
from dataclasses import dataclass
from typing import Protocol, Self, TypeVar

from hilrig.errors import HilrigError

T_co = TypeVar("T_co", covariant=True)
T_contra = TypeVar("T_contra", contravariant=True)


@dataclass(frozen=True, slots=True)
class LinkStatus:
    """Health of a device link at one instant.

    ``age_ns`` is how old the newest sample is (None before the first); ``rate_hz`` the sample
    rate over the last second or so (0 when silent); ``stalls`` counts silences longer than the
    driver's stall limit; ``reconnects`` the times the link was reopened after a loss;
    ``errors`` every exception caught in ``poll``, the last one in ``last_error``.
    """

    endpoint: str
    connected: bool
    samples: int
    rate_hz: float
    age_ns: int | None
    stalls: int
    reconnects: int
    errors: int
    last_error: str


class Device(Protocol):
    """Opened by ``connect()``, released by ``close()``; ``with device:`` does both."""

    def connect(self) -> None: ...

    def close(self) -> None: ...

    @property
    def is_connected(self) -> bool: ...

    def fileno(self) -> int:
        """The descriptor to select() on for input; -1 while the link is down."""
        ...

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class Reader(Device, Protocol[T_co]):
    """A device streaming samples, each carrying its host receive time ``t_ns``."""

    def poll(self, now_ns: int) -> Collection[T_co]:
        """Read what is available, stamped ``now_ns``; the new samples, oldest first (a list,
        or rows of an array the next poll reuses)."""
        ...

    def latest(self) -> T_co | None:
        """The newest sample, or None before the first."""
        ...

    def status(self) -> LinkStatus: ...


class Writer(Device, Protocol[T_contra]):
    """A device taking commands; ``write`` sends without waiting, ``poll`` takes the replies."""

    def write(self, value: T_contra) -> None: ...

    def poll(self, now_ns: int) -> None: ...


class RateMeter:
    """Samples per second over windows of ``window_ns``; 0 once silent for two windows."""

    def __init__(self, window_ns: int = 500_000_000) -> None:
        self._window_ns = window_ns
        self._t0_ns = 0
        self._n0 = 0
        self._rate_hz = 0.0

    def update(self, now_ns: int, total: int) -> None:
        """``total`` samples have arrived by ``now_ns``."""
        if now_ns - self._t0_ns >= self._window_ns:
            if self._t0_ns:
                self._rate_hz = (total - self._n0) * 1e9 / (now_ns - self._t0_ns)
            self._t0_ns, self._n0 = now_ns, total

    def rate_hz(self, age_ns: int | None) -> float:
        """The rate, given the age of the newest sample."""
        return 0.0 if age_ns is None or age_ns > 2 * self._window_ns else self._rate_hz


def error_text(err: Exception) -> str:
    """One line for ``last_error``: hilrig's own message, or the type and message of others."""
    return str(err) if isinstance(err, HilrigError) else f"{type(err).__name__}: {err}"


def wait_readable(fd: int, timeout_s: float) -> None:
    """Block until ``fd`` is readable or ``timeout_s`` passed (a short sleep if ``fd`` < 0).

    For the blocking helpers (connect, tare), never for the real-time loop.
    """
    if fd < 0:
        time.sleep(min(timeout_s, 0.005))
    else:
        select.select([fd], [], [], max(timeout_s, 0.0))
