"""The robot's joint-state TCP stream, emulated: frames at a fixed rate to every client.

Binds 127.0.0.1 with an OS-chosen port unless told otherwise. One thread accepts clients and
streams ``source(sequence)`` as robot_state_codec frames, paced by absolute deadlines so the
rate does not drift. A client too slow to take its bytes loses whole frames (counted), never
half of one. Faults: ``drop_links()`` closes every client socket, ``stall(s)`` stops sending,
``inject(bytes)`` sends garbage between frames.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from hilrig.drivers.robot_state_codec import RobotState, encode

MAX_BACKLOG_BYTES = 64 * 1024  # per client: beyond this, frames are dropped for that client


@dataclass
class ServerStats:
    """Counters since start."""

    ticks: int = 0  # frames produced (sent to every connected client, if any)
    frames_sent: int = 0  # frames queued to clients, summed over clients
    frames_dropped: int = 0  # not sent to a slow client
    clients_accepted: int = 0
    links_dropped: int = 0
    late_ticks: int = 0  # ticks that started after their deadline had passed by > 1 period


class _Client:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.backlog = bytearray()


class EmulatedRobotStateServer:
    """Streams joint-state frames at ``rate_hz`` over TCP; start()/stop() or a with block."""

    def __init__(
        self,
        source: Callable[[int], RobotState],
        *,
        rate_hz: float = 1000.0,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        self._source = source
        self._period_ns = round(1e9 / rate_hz)
        self._listener = socket.create_server((host, port), reuse_port=False)
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._clients: list[_Client] = []
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._stall_until_ns = 0
        self._garbage = bytearray()
        self._drop = False
        self._down_until_ns = 0
        self._thread = threading.Thread(target=self._run, daemon=True, name="robot-state")
        self.stats = ServerStats()

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        for client in self._clients:
            client.sock.close()
        self._listener.close()

    def __enter__(self) -> EmulatedRobotStateServer:
        self.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.stop()

    def drop_links(self, down_s: float = 0.0) -> None:
        """Close every client connection; for ``down_s`` the robot then stays silent (new
        connections wait in the listen backlog), like a cable pulled and plugged back."""
        with self._lock:
            self._drop = True
            self._down_until_ns = time.monotonic_ns() + round(down_s * 1e9)

    def stall(self, duration_s: float) -> None:
        """Send nothing for ``duration_s`` (frames of that time are skipped, not queued)."""
        with self._lock:
            self._stall_until_ns = time.monotonic_ns() + round(duration_s * 1e9)

    def inject(self, garbage: bytes) -> None:
        """Send ``garbage`` to every client before the next frame."""
        with self._lock:
            self._garbage += garbage

    def _run(self) -> None:
        sequence = 0
        deadline = time.monotonic_ns()
        while not self._stop.is_set():
            with self._lock:
                now = time.monotonic_ns()
                down = now < self._down_until_ns
                stalled = now < self._stall_until_ns or down
                extra, self._garbage = bytes(self._garbage), bytearray()
                drop, self._drop = self._drop, False
            if drop:
                self._close_all()
            if not down:
                self._accept()
            if not stalled:
                self._send(extra + encode(self._source(sequence)))
                self.stats.ticks += 1
            sequence += 1
            deadline += self._period_ns
            now = time.monotonic_ns()
            if now - deadline > self._period_ns:
                self.stats.late_ticks += 1
                deadline = now  # do not burst to catch up
            else:
                self._stop.wait(max(0, deadline - now) / 1e9)

    def _accept(self) -> None:
        try:
            sock, _ = self._listener.accept()
        except BlockingIOError:
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._clients.append(_Client(sock))
        self.stats.clients_accepted += 1

    def _close_all(self) -> None:
        for client in self._clients:
            client.sock.close()
            self.stats.links_dropped += 1
        self._clients.clear()

    def _send(self, frame: bytes) -> None:
        for client in list(self._clients):
            if len(client.backlog) + len(frame) > MAX_BACKLOG_BYTES:
                self.stats.frames_dropped += 1
            else:
                client.backlog += frame
                self.stats.frames_sent += 1
            try:
                sent = client.sock.send(client.backlog)
            except BlockingIOError:
                continue
            except OSError:
                client.sock.close()
                self._clients.remove(client)
                continue
            del client.backlog[:sent]
