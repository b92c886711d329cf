"""Robot joint state over TCP: a reader thread keeping the newest frame, reconnecting on loss.

``latest()`` never blocks: it returns the newest decoded frame with its host receive time
(time.monotonic_ns), or None before the first one. ``staleness_ns()`` tells how old it is, which
the real-time loop compares against its limit to hold the robot on a lost link. The decoder is
pluggable (``decoder_factory``) so a real controller's format can replace hilrig's. No exception
escapes the thread: the last one is kept in ``last_error`` and every reconnect is counted.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from hilrig.drivers.robot_state_codec import DecoderStats, RobotState, RobotStateDecoder
from hilrig.errors import LinkError


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


class RobotStateClient:
    """Reads the joint-state stream at ``host:port``; use as a context manager."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        decoder_factory: Callable[[], StateDecoder] = RobotStateDecoder,
        connect_timeout_s: float = 1.0,
        backoff_s: tuple[float, float] = (0.01, 1.0),
    ) -> None:
        self.endpoint = (host, port)
        self._decoder = decoder_factory()
        self._connect_timeout_s = connect_timeout_s
        self._backoff_s = backoff_s
        self._latest: ReceivedState | None = None
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self._thread = threading.Thread(target=self._run, daemon=True, name="robot-state-client")
        self.connected = False
        self.reconnects = 0
        self.bytes_received = 0
        self.last_error: Exception | None = None

    @property
    def stats(self) -> DecoderStats:
        """The decoder's counters (frames, CRC errors, gaps, bytes dropped...)."""
        return self._decoder.stats

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        sock = self._sock
        if sock is not None:
            sock.close()  # unblocks recv
        self._thread.join(timeout=5)

    def __enter__(self) -> RobotStateClient:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def latest(self) -> ReceivedState | None:
        """The newest frame and its receive time; never blocks."""
        return self._latest

    def staleness_ns(self, now_ns: int | None = None) -> int | None:
        """How old the newest frame is (ns), or None before the first frame."""
        latest = self._latest
        if latest is None:
            return None
        return (time.monotonic_ns() if now_ns is None else now_ns) - latest.t_ns

    def _run(self) -> None:
        delay_s = self._backoff_s[0]
        first = True
        while not self._stop.is_set():
            try:
                sock = socket.create_connection(self.endpoint, timeout=self._connect_timeout_s)
            except OSError as err:
                self.last_error = LinkError(f"robot state {self._where()}: {err}")
                self._stop.wait(delay_s)
                delay_s = min(2 * delay_s, self._backoff_s[1])
                continue
            if not first:
                self.reconnects += 1
            first = False
            delay_s = self._backoff_s[0]
            self._decoder.reset()
            self._sock = sock
            self.connected = True
            try:
                self._read(sock)
            except OSError as err:
                if not self._stop.is_set():
                    self.last_error = LinkError(f"robot state {self._where()}: {err}")
            finally:
                self.connected = False
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
                self.last_error = LinkError(f"robot state {self._where()}: closed by the robot")
                return
            self.bytes_received += count
            frames = self._decoder.feed(bytes(buffer[:count]))
            if frames:
                self._latest = ReceivedState(now, frames[-1])

    def _where(self) -> str:
        return f"tcp://{self.endpoint[0]}:{self.endpoint[1]}"
