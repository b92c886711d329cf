"""The shape every device driver follows: connect, read or write, close; a context manager.

Like LeRobot's device classes, but structural: a driver satisfies :class:`Reader` or
:class:`Writer` by having the methods, and may subclass them to inherit ``__enter__`` (connect)
and ``__exit__`` (close). Readers run their own I/O thread: ``latest()`` never blocks, and no
exception escapes the thread (it is counted in :class:`LinkStatus` instead).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, Self, TypeVar

T_co = TypeVar("T_co", covariant=True)
T_contra = TypeVar("T_contra", contravariant=True)


@dataclass(frozen=True, slots=True)
class LinkStatus:
    """Health of a device link at one instant.

    ``age_ns`` is how old the newest sample is (None before the first); ``rate_hz`` the sample
    rate over the last second or so (0 when silent); ``stalls`` counts silences longer than the
    driver's stall limit; ``reconnects`` the times the link was reopened after a loss;
    ``errors`` every exception caught in the I/O thread, the last one in ``last_error``.
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

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class Reader(Device, Protocol[T_co]):
    """A device streaming samples, each carrying its host receive time ``t_ns``."""

    def latest(self) -> T_co | None:
        """The newest sample, or None before the first; never blocks."""
        ...

    def drain(self) -> Sequence[T_co]:
        """Every sample received since the last drain (oldest first, bounded); never blocks."""
        ...

    def status(self) -> LinkStatus: ...


class Writer(Device, Protocol[T_contra]):
    """A device taking commands; ``write`` never blocks the caller's loop."""

    def write(self, value: T_contra) -> None: ...
