"""Session ids: unique across machines and processes, in the order they were minted.

A session id is a ULID (python-ulid): 26 characters of Crockford's base32, 48 bits of
milliseconds since the epoch then 80 random bits, e.g. ``01KCQ4X2ZJ8M3N6P9R1T5V7W0Y``. Ids of
two processes or machines differ by their random bits even when minted in the same
millisecond; ids minted by one process sort in the order they were minted, within a
millisecond too (the random part counts up) and when the wall clock steps back (the clock
never goes back here). A forked child starts a sequence of its own, so parent and child never
mint the same id. Digits and capitals only: an id is a file name and a hive partition value as
it is.

A session is known by its files, not by its id alone (a copied file, or an older id of a
second's resolution, claims the id of another session): :func:`written_as` says which file a
split part belongs to.
"""

from __future__ import annotations

import os
import threading
import time
import weakref
from collections.abc import Callable

from ulid import ULIDGenerator


def _wall_ms() -> int:
    return time.time_ns() // 1_000_000


class SessionIds:
    """A source of session ids; ``clock_ms`` gives milliseconds since the epoch."""

    def __init__(self, clock_ms: Callable[[], int] = _wall_ms) -> None:
        self._clock_ms = clock_ms
        self._last_ms = 0
        self._forget()
        forget = weakref.WeakMethod(self._forget)
        os.register_at_fork(after_in_child=lambda: None if (f := forget()) is None else f())

    def mint(self) -> str:
        """A new session id."""
        return str(self._generator.generate())

    def _clock(self) -> int:
        """The clock's milliseconds, never less than the last reading's."""
        with self._lock:
            self._last_ms = max(self._last_ms, self._clock_ms())
            return self._last_ms

    def _forget(self) -> None:
        """Start a new sequence (a forked child must not count on from its parent's ids)."""
        self._lock = threading.Lock()
        self._generator = ULIDGenerator(clock=self._clock)


_IDS = SessionIds()


def new_session_id() -> str:
    """A new session id (see the module's docstring)."""
    return _IDS.mint()


def written_as(path: str, part: int) -> str:
    """The path a session was written to, given the path of its split part number ``part``
    (``s_002.mcap`` -> ``s.mcap``, as ``hilrig.recording.writer.part_path`` names parts); a
    file not named as a part is its own."""
    stem, dot, suffix = path.rpartition(".")
    tail = f"_{part:03d}"
    return f"{stem.removesuffix(tail)}{dot}{suffix}" if dot and stem.endswith(tail) else path
