"""One session at a time on a machine: the lock every recorded session holds while it runs.

Two sessions on one small machine spoil each other's deadlines (two real-time loops and two
emulated rigs on two cores), and two on one real rig would command one robot twice. So
``record_session`` first takes an exclusive ``flock`` on :data:`LOCK_PATH` (in the system's
temporary folder, shared by every user and every clone on the machine). A session that finds it
taken says so once and waits until it is free or its ``stop`` is set; the kernel releases the
lock when its holder ends, however it ends (a killed session leaves no stale lock behind).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

from hilrig.errors import HilrigError, StoppedWaitingError

LOCK_PATH = Path(tempfile.gettempdir()) / "hilrig-session.lock"
POLL_S = 0.1  # how often a waiting session looks again (and at its stop)
WAITING = "another hilrig session is running on this machine; this one starts when it ends"
STOPPED = "stopped while waiting for the other session: nothing recorded"


@contextlib.contextmanager
def one_session_at_a_time(
    stop: threading.Event,
    on_wait: Callable[[str], None] | None = None,
    *,
    path: Path = LOCK_PATH,
) -> Iterator[None]:
    """Hold the machine's session lock for the ``with`` block. While another session holds it,
    ``on_wait`` gets WAITING once and this waits; raises StoppedWaitingError if ``stop`` is set
    meanwhile, HilrigError (one line) if the lock file cannot be opened."""
    fd = _open(path)
    try:
        waited = False
        while not _try_lock(fd):
            if not waited and on_wait is not None:
                on_wait(WAITING)
            waited = True
            if stop.wait(POLL_S):
                raise StoppedWaitingError(STOPPED)
        yield
    finally:
        os.close(fd)  # releases the lock


def _open(path: Path) -> int:
    """A read-only descriptor of the lock file (flock needs no write access), created if absent.
    An existing file is opened without O_CREAT: in a sticky temporary folder the kernel refuses
    O_CREAT on another user's file (fs.protected_regular)."""
    try:
        try:
            return os.open(path, os.O_RDONLY | os.O_CLOEXEC)
        except FileNotFoundError:
            return os.open(path, os.O_RDONLY | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as err:
        raise HilrigError(f"session lock {path}: cannot open it ({err.strerror})") from None


def _try_lock(fd: int) -> bool:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True
