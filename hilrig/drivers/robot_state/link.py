"""Robot joint state over TCP, polled from the caller's loop; reconnects on loss.

Follows the driver shape of ``hilrig.drivers.base``: the loop selects on ``fileno()`` and calls
``poll(now_ns)``, which takes everything waiting on the non-blocking socket (``recv_into`` a
preallocated buffer, TCP_NODELAY) and returns the decoded frames stamped ``now_ns``;
``latest()`` is the newest and ``status().age_ns`` tells how old it is, which the loop compares
with its limit to hold the robot on a lost link. The decoder is pluggable (``decoder_factory``)
so a real controller's format can replace hilrig's. ``poll`` never raises: each error is
counted, the last kept in ``last_error``, and the link reopened with backoff. Connecting is
non-blocking too (``connect_ex``, then writability checked by the next polls): no thread ever.
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Callable
from typing import NamedTuple, Protocol

from hilrig.drivers.base import LinkStatus, RateMeter, Reader, error_text, wait_readable
from hilrig.drivers.reconnect import Backoff, start_tcp_connect, tcp_connected
from hilrig.drivers.robot_state.wire import DecoderStats, RobotState, RobotStateDecoder
from hilrig.errors import LinkError

RECV_BYTES = 65536  # per recv: 385 frames, far more than arrive between two 1 kHz ticks


class StateDecoder(Protocol):
    """Turns received bytes into frames; counts what it drops."""

    stats: DecoderStats

    def feed(self, data: bytes) -> list[RobotState]: ...
    def reset(self) -> None: ...


class ReceivedState(NamedTuple):
    """A frame and the host monotonic time (ns) of the poll that received its last byte (a
    named tuple: cheap to make at 1 kHz)."""

    t_ns: int
    state: RobotState


class RobotStateClient(Reader[ReceivedState]):
    """Reads the joint-state stream at ``host:port``; ``with client:`` connects and closes."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        decoder_factory: Callable[[], StateDecoder] = RobotStateDecoder,
        connect_timeout_s: float = 1.0,
        stall_after_s: float = 0.05,
        backoff_s: tuple[float, float] = (0.01, 1.0),
    ) -> None:
        self.endpoint = (host, port)
        self._decoder = decoder_factory()
        self._connect_timeout_ns = round(connect_timeout_s * 1e9)
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._backoff = Backoff(backoff_s)
        self._buffer = bytearray(RECV_BYTES)
        self._view = memoryview(self._buffer)
        self._sock: socket.socket | None = None  # connecting or connected
        self._fd = -1  # the socket's once connected
        self._connect_started_ns = 0
        self._wanted = False  # between connect() and close(): poll reopens a lost link
        self._linked_before = False
        self._unreturned: list[ReceivedState] = []  # read by connect(), returned by next poll
        self._latest: ReceivedState | None = None
        self._rate = RateMeter()
        self.reconnects = 0
        self.stalls = 0
        self.errors = 0
        self.bytes_received = 0
        self.last_error = ""

    def decoder_stats(self) -> DecoderStats:
        """The decoder's counters (frames, CRC errors, gaps, bytes dropped...)."""
        return self._decoder.stats

    def connect(self, *, first_frame_timeout_s: float | None = 1.0) -> None:
        """Start connecting; wait for the first frame unless the timeout is None.

        Raises LinkError if no valid frame arrives within ``first_frame_timeout_s`` (with None,
        ``poll`` keeps trying to connect with backoff).
        """
        if self._wanted:
            return
        self._wanted = True
        self._linked_before = False
        self._backoff.succeeded()
        self._unreturned = self.poll(time.monotonic_ns())
        if first_frame_timeout_s is None:
            return
        deadline_ns = time.monotonic_ns() + round(first_frame_timeout_s * 1e9)
        while not self._unreturned:
            left_ns = deadline_ns - time.monotonic_ns()
            if left_ns <= 0:
                self.close()
                raise LinkError(
                    f"robot state {self._where()}: no valid frame within {first_frame_timeout_s}"
                    f" s ({self.last_error or 'nothing received'})"
                )
            wait_readable(self._fd, left_ns / 1e9)
            self._unreturned = self.poll(time.monotonic_ns())

    def close(self) -> None:
        """Close the socket; poll no longer reopens it. Idempotent."""
        self._wanted = False
        self._unreturned = []
        self._drop()

    @property
    def is_connected(self) -> bool:
        """True while the socket is connected."""
        return self._fd >= 0

    def fileno(self) -> int:
        """The connected socket's descriptor; -1 while down or still connecting."""
        return self._fd

    def poll(self, now_ns: int) -> list[ReceivedState]:
        """The frames received now (stamped ``now_ns``), oldest first; never blocks or raises."""
        try:
            received = self._pump(now_ns)
        except Exception as err:  # whatever happens (even a bug), the caller's loop carries on
            self.errors += 1
            self.last_error = error_text(err)
            self._drop()
            self._backoff.failed(now_ns)
            received = []
        if self._unreturned:
            received, self._unreturned = self._unreturned + received, []
        return received

    def latest(self) -> ReceivedState | None:
        """The newest frame and its receive time."""
        return self._latest

    def status(self) -> LinkStatus:
        latest = self._latest
        age_ns = None if latest is None else time.monotonic_ns() - latest.t_ns
        return LinkStatus(
            endpoint=self._where(),
            connected=self.is_connected,
            samples=self._decoder.stats.frames,
            rate_hz=self._rate.rate_hz(age_ns),
            age_ns=age_ns,
            stalls=self.stalls,
            reconnects=self.reconnects,
            errors=self.errors,
            last_error=self.last_error,
        )

    # -- the link ----------------------------------------------------------------------------

    def _pump(self, now_ns: int) -> list[ReceivedState]:
        """Connect when due, then read and decode; raises on a lost link."""
        if self._sock is None:
            if not (self._wanted and self._backoff.due(now_ns)):
                return []
            self._sock = start_tcp_connect(self.endpoint)
            self._connect_started_ns = now_ns
        if self._fd < 0 and not self._connected(now_ns):
            return []
        sock, buffer, frames = self._sock, self._buffer, []
        assert sock is not None
        while True:
            try:
                count = sock.recv_into(buffer)
            except BlockingIOError:
                break
            if count == 0:
                raise LinkError(f"robot state {self._where()}: closed by the robot")
            self.bytes_received += count
            frames += self._decoder.feed(bytes(self._view[:count]))
            if count < len(buffer):
                break
        if not frames:
            return []
        latest = self._latest
        if latest is not None and now_ns - latest.t_ns > self._stall_after_ns:
            self.stalls += 1
        received = [ReceivedState(now_ns, frame) for frame in frames]
        self._latest = received[-1]
        self._rate.update(now_ns, self._decoder.stats.frames)
        return received

    def _connected(self, now_ns: int) -> bool:
        """Whether the connect under way completed; raises if it failed or took too long."""
        assert self._sock is not None
        if not tcp_connected(self._sock):
            if now_ns - self._connect_started_ns > self._connect_timeout_ns:
                raise LinkError(f"robot state {self._where()}: connect timed out")
            return False
        self._fd = self._sock.fileno()
        self._decoder.reset()
        self._backoff.succeeded()
        if self._linked_before:
            self.reconnects += 1
        self._linked_before = True
        return True

    def _drop(self) -> None:
        sock, self._sock, self._fd = self._sock, None, -1
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.close()

    def _where(self) -> str:
        return f"tcp://{self.endpoint[0]}:{self.endpoint[1]}"
