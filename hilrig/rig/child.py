"""One way to run a helper process: spawned, deaf to Ctrl-C, talking over a Pipe.

:meth:`ChildProcess.start` spawns ``target(conn, *args)`` with SIGINT blocked across the spawn
(a Ctrl-C while the child starts up stays pending, the mask being inherited, until the child
ignores it): the parent handles Ctrl-C and then stops its children in order. The child reports
with :func:`report` (``(kind, value)`` pairs, ``"error"`` carrying a one-line message) and may
receive requests on the same duplex ``conn``; the parent waits for a report with
:meth:`~ChildProcess.wait_report` and ends the child with :meth:`~ChildProcess.stop` (join, then
kill). A child whose parent is gone sees EOF on ``conn``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
from collections.abc import Callable
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any, Final

from hilrig.errors import HilrigError

# "spawn": the parent runs driver threads, and forking a threaded process can copy a lock held
# by another thread into the child. "forkserver" would be as safe, but its children are the
# fork server's, not the parent's: a child could not watch its parent's pid.
START_METHOD: Final = "spawn"
CONTEXT: Final = multiprocessing.get_context(START_METHOD)


def report(conn: Connection, kind: str, value: object = None) -> None:
    """Child side: tell the parent ``(kind, value)``; nothing if the parent is gone."""
    with contextlib.suppress(OSError):
        conn.send((kind, value))


def _run(target: Callable[..., None], conn: Connection, args: tuple[object, ...]) -> None:
    """The child's entry: ignore SIGINT (it was blocked by the parent across the spawn), run."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    target(conn, *args)


class ChildProcess:
    """A spawned daemon child named ``name``; failures raise ``error`` (a HilrigError class)
    with ``label`` first, e.g. ``"recorder of s.mcap: exited with code -9 before reporting
    ready"``."""

    def __init__(self, name: str, label: str, error: type[HilrigError] = HilrigError) -> None:
        self.name, self.label, self.error = name, label, error
        self._process: BaseProcess | None = None
        self._conn: Connection | None = None

    def start(self, target: Callable[..., None], args: tuple[object, ...] = ()) -> None:
        """Spawn ``target(conn, *args)`` (module-level, picklable) and return at once."""
        if self._process is not None:
            raise self.error(f"{self.label}: already started")
        self._conn, conn = CONTEXT.Pipe()
        process = CONTEXT.Process(
            target=_run, args=(target, conn, args), name=self.name, daemon=True
        )
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        self._process = process
        conn.close()  # the child's end: EOF here once the child is gone

    @property
    def started(self) -> bool:
        return self._process is not None

    @property
    def pid(self) -> int | None:
        """The child's pid (None before :meth:`start`)."""
        return None if self._process is None else self._process.pid

    @property
    def exitcode(self) -> int | None:
        """The child's exit code (negative: the signal that ended it); None while it runs."""
        return None if self._process is None else self._process.exitcode

    @property
    def sentinel(self) -> int:
        """A file descriptor readable once the child has ended (its process's sentinel)."""
        if self._process is None:
            raise self.error(f"{self.label}: not started")
        return self._process.sentinel

    def alive(self) -> bool:
        """The child runs: one ``waitpid(WNOHANG)`` system call, no I/O."""
        return self._process is not None and self._process.is_alive()

    def send(self, message: object) -> None:
        """Send ``message`` (pickled) to the child; raises ``error`` if it is gone."""
        try:
            self._connection().send(message)
        except OSError as err:
            raise self.error(f"{self.label}: gone ({err.strerror or err})") from None

    def poll(self, timeout_s: float = 0.0) -> bool:
        """A report, or the child's end, is waiting (at most ``timeout_s`` for it)."""
        return self._connection().poll(timeout_s)

    def fileno(self) -> int:
        """The pipe's descriptor: readable once a report, or the child's end, is waiting."""
        return self._connection().fileno()

    def next_report(self) -> tuple[str, Any]:
        """The next ``(kind, value)`` report as it is (blocks); ``("ended", exit code)`` once
        the child is gone."""
        try:
            kind, value = self._connection().recv()
        except (EOFError, OSError):
            self._join()
            return "ended", self.exitcode
        return str(kind), value

    def receive(self, kind: str) -> Any:
        """The value of the child's next report, which should be ``kind`` (blocks). Raises
        ``error`` with the child's own message, or with how it ended if it sent none."""
        return self.expect(self.next_report(), kind)

    def expect(self, report: tuple[str, Any], kind: str) -> Any:
        """The value of ``report`` (from :meth:`next_report`), which should be ``kind``; raises
        as :meth:`receive` does."""
        got, value = report
        if got == "ended":
            raise self.error(f"{self.label}: exited with code {value} before reporting {kind}")
        if got == "error":
            self._join()  # it exits right after saying so
            raise self.error(f"{self.label}: {value}")
        if got != kind:
            raise self.error(f"{self.label}: reported {got} instead of {kind}")
        return value

    def wait_report(self, kind: str, timeout_s: float) -> Any:
        """:meth:`receive` within ``timeout_s``; a child that says nothing by then is killed."""
        if not self.poll(timeout_s):
            self.kill()
            raise self.error(f"{self.label}: no {kind} report within {timeout_s:g} s; killed it")
        return self.receive(kind)

    def stop(self, timeout_s: float, *, message: object = None) -> bool:
        """Send ``message`` (unless None), wait up to ``timeout_s`` for the child to exit, kill
        it if it did not. True if it exited by itself (or never started)."""
        process = self._process
        if process is None:
            return True
        if message is not None and process.is_alive():
            with contextlib.suppress(OSError):  # it may be gone already
                self._connection().send(message)
        process.join(timeout_s)
        if process.is_alive():
            self.kill()
            return False
        return True

    def kill(self) -> None:
        """SIGKILL the child and reap it."""
        if self._process is not None:
            self._process.kill()
            self._process.join()

    def close(self) -> None:
        """Kill the child if it still runs and close the Pipe."""
        if self.alive():
            self.kill()
        if self._conn is not None:
            self._conn.close()

    def _join(self) -> None:
        if self._process is not None:
            self._process.join()

    def _connection(self) -> Connection:
        if self._conn is None:
            raise self.error(f"{self.label}: not started")
        return self._conn
