"""A session's stop that says why: the signal (or caller) that set it becomes the recording's
``ended_by`` (:mod:`hilrig.recording.outcome`)."""

from __future__ import annotations

import signal
import threading
from types import FrameType

from hilrig.recording.outcome import INTERRUPTED, STOPPED, TERMINATED

#: What each signal a session handles says as ``ended_by``.
SIGNAL_ENDS = {signal.SIGINT: INTERRUPTED, signal.SIGTERM: TERMINATED}


class SessionStop(threading.Event):
    """A :class:`threading.Event` with the reason it was first set (:data:`STOPPED` for a plain
    ``set()``); :meth:`on_signal` is a signal handler (SIGINT, SIGTERM). The loop checks it
    every tick, and its wait is bounded by two periods, so no signal waits on it."""

    def __init__(self) -> None:
        super().__init__()
        self.reason = ""

    def stop(self, reason: str) -> None:
        """Set it, keeping the first reason given."""
        if not self.reason:
            self.reason = reason
        self.set()

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        """A signal handler: set it with the signal's reason (:data:`SIGNAL_ENDS`)."""
        self.stop(SIGNAL_ENDS.get(signal.Signals(signum), f"signal {signum}"))


def stop_reason(stop: threading.Event) -> str:
    """Why ``stop`` is set: a :class:`SessionStop`'s reason, else :data:`STOPPED`."""
    return getattr(stop, "reason", "") or STOPPED
