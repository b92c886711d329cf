"""Bytes queued for a non-blocking pty or socket, with an exact count of frames sent.

A frame counts as sent once its last byte has been handed to the kernel; one that does not fit
under ``limit`` unsent bytes is dropped whole (counted), never cut. Garbage (faults) is queued
without counting. ``write`` returns the bytes it took (0 when the kernel buffer is full) and
raises OSError when the link is gone.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

Writer = Callable[[bytes | bytearray], int]


class Outbox:
    """The unsent tail of a stream; ``put`` a frame, ``flush`` again on later slots."""

    def __init__(self, write: Writer, limit: int) -> None:
        self._write = write
        self._limit = limit
        self._pending = bytearray()
        self._ends: deque[int] = deque()  # end offsets of unsent frames in the queued stream
        self._queued = 0  # bytes queued since creation
        self._written = 0  # bytes handed to the kernel since creation
        self.frames_sent = 0
        self.frames_dropped = 0

    def put(self, data: bytes, *, frame: bool = True) -> None:
        """Queue ``data`` (a whole frame unless ``frame`` is False) and write what fits."""
        if not self._pending and len(data) <= self._limit:  # the usual case: straight through
            written = self._write(data)
            self._queued += len(data)
            self._written += written
            if written < len(data):
                self._pending += data[written:]
                if frame:
                    self._ends.append(self._queued)
            elif frame:
                self.frames_sent += 1
            return
        self.flush()  # first: a backlog at its limit drains as soon as the reader reads again
        if frame and len(self._pending) + len(data) > self._limit:
            self.frames_dropped += 1
            return
        self._pending += data
        self._queued += len(data)
        if frame:
            self._ends.append(self._queued)
        self.flush()

    def flush(self) -> None:
        """Write as much as the kernel takes now."""
        if not self._pending:
            return
        written = self._write(self._pending)
        del self._pending[:written]
        self._written += written
        ends = self._ends
        while ends and ends[0] <= self._written:
            ends.popleft()
            self.frames_sent += 1

    def discard(self) -> None:
        """The link is gone: unsent frames count as dropped."""
        self.frames_dropped += len(self._ends)
        self._ends.clear()
        self._pending.clear()

    @property
    def unsent(self) -> int:
        """Bytes queued but not yet written."""
        return len(self._pending)
