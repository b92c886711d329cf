"""Robot joint state over TCP: a reader thread keeping the newest frame, reconnecting on loss.

Follows the driver shape of ``hilrig.drivers.base``: ``latest()`` never blocks and returns the
newest decoded frame with its host receive time (time.monotonic_ns); ``status().age_ns`` tells
how old it is, which the real-time loop compares with its limit to hold the robot on a lost
link. The decoder is pluggable (``decoder_factory``) so a real controller's format can replace
hilrig's. No exception escapes the thread: each is counted, the last kept in ``last_error``,
and the link is reopened with backoff.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from hilrig.drivers.base import LinkStatus, Reader
from hilrig.drivers.robot_state_codec import DecoderStats, RobotState, RobotStateDecoder
from hilrig.errors import LinkError

HISTORY = 4096  # frames kept for drain(): 4 s at 1 kHz
RATE_WINDOW_NS = 500_000_000


class StateDecoder(Protocol):
    """Turns received bytes into frames; counts what it drops."""

    stats: DecoderStats

    def feed(self, data: bytes) -> list[RobotState]: ...
    def reset(self) -> None: ...


@dataclass(frozen=True)
class ReceivedState:
    """A frame and the host monotonic time (ns) its last byte was received."""

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
        self._connect_timeout_s = connect_timeout_s
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._backoff_s = backoff_s
        self._latest: ReceivedState | None = None
        self._history: deque[ReceivedState] = deque(maxlen=HISTORY)
        self._first_frame = threading.Event()
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._linked = False
        self._rate_hz = 0.0
        self._rate_window: tuple[int, int] = (0, 0)  # (t_ns, frames) at the window's start
        self.reconnects = 0
        self.stalls = 0
        self.errors = 0
        self.bytes_received = 0
        self.last_error = ""

    def decoder_stats(self) -> DecoderStats:
        """The decoder's counters (frames, CRC errors, gaps, bytes dropped...)."""
        return self._decoder.stats

    def connect(self, *, first_frame_timeout_s: float | None = 1.0) -> None:
        """Start the reader; wait for the first frame if asked.

        Raises LinkError if no valid frame arrives within ``first_frame_timeout_s`` (None: do
        not wait; the reader keeps trying to connect with backoff).
        """
        if self.is_connected:
            return
        self._stop.clear()
        self._first_frame.clear()
        self._thread = threading.Thread(target=self._run, daemon=True, name="robot-state")
        self._thread.start()
        if first_frame_timeout_s is not None and not self._first_frame.wait(first_frame_timeout_s):
            self.close()
            raise LinkError(
                f"robot state {self._where()}: no valid frame within {first_frame_timeout_s} s "
                f"({self.last_error or 'nothing received'})"
            )

    def close(self) -> None:
        """Stop the reader (joined) and close the socket. Idempotent."""
        self._stop.set()
        sock = self._sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)  # unblocks recv
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None

    @property
    def is_connected(self) -> bool:
        """True while the reader runs and its socket is connected."""
        return self._thread is not None and self._thread.is_alive() and self._linked

    def latest(self) -> ReceivedState | None:
        """The newest frame and its receive time; never blocks."""
        return self._latest

    def drain(self) -> list[ReceivedState]:
        """Frames since the last drain, oldest first (at most the last ``HISTORY``)."""
        history = self._history
        return [history.popleft() for _ in range(len(history))]

    def status(self) -> LinkStatus:
        latest = self._latest
        age_ns = None if latest is None else time.monotonic_ns() - latest.t_ns
        return LinkStatus(
            endpoint=self._where(),
            connected=self.is_connected,
            samples=self._decoder.stats.frames,
            rate_hz=0.0 if age_ns is None or age_ns > RATE_WINDOW_NS else self._rate_hz,
            age_ns=age_ns,
            stalls=self.stalls,
            reconnects=self.reconnects,
            errors=self.errors,
            last_error=self.last_error,
        )

    def _run(self) -> None:
        delay_s = self._backoff_s[0]
        first = True
        while not self._stop.is_set():
            try:
                sock = socket.create_connection(self.endpoint, timeout=self._connect_timeout_s)
            except OSError as err:
                self._error(err)
                self._stop.wait(delay_s)
                delay_s = min(2 * delay_s, self._backoff_s[1])
                continue
            if not first:
                self.reconnects += 1
            first = False
            delay_s = self._backoff_s[0]
            self._decoder.reset()
            self._sock = sock
            self._linked = True
            try:
                self._read(sock)
            except Exception as err:  # whatever happens (even a bug), the thread carries on
                if not self._stop.is_set():
                    self._error(err)
            finally:
                self._linked = False
                self._sock = None
                sock.close()

    def _read(self, sock: socket.socket) -> None:
        sock.settimeout(None)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        buffer = bytearray(65536)
        while not self._stop.is_set():
            count = sock.recv_into(buffer)
            now = time.monotonic_ns()
            if count == 0:
                raise LinkError(f"robot state {self._where()}: closed by the robot")
            self.bytes_received += count
            frames = self._decoder.feed(bytes(buffer[:count]))
            if not frames:
                continue
            latest = self._latest
            if latest is not None and now - latest.t_ns > self._stall_after_ns:
                self.stalls += 1
            for frame in frames:
                self._history.append(ReceivedState(now, frame))
            self._latest = ReceivedState(now, frames[-1])
            self._first_frame.set()
            self._update_rate(now)

    def _update_rate(self, now_ns: int) -> None:
        t0, n0 = self._rate_window
        frames = self._decoder.stats.frames
        if now_ns - t0 >= RATE_WINDOW_NS:
            if t0:
                self._rate_hz = (frames - n0) * 1e9 / (now_ns - t0)
            self._rate_window = (now_ns, frames)

    def _error(self, err: Exception) -> None:
        self.errors += 1
        self.last_error = str(err) if isinstance(err, LinkError) else f"{type(err).__name__}: {err}"

    def _where(self) -> str:
        return f"tcp://{self.endpoint[0]}:{self.endpoint[1]}"
