"""The robot's joint-state TCP stream, emulated: one frame per slot to every client.

Binds 127.0.0.1 with an OS-chosen port unless told otherwise. A device of a :class:`SlotLoop` (or
alone with ``start()``/``stop()``): the loop accepts clients as they connect, and each ``tick``
sends ``source(sequence)`` as a wire frame (robot_state/wire.py; a source may give the frame's
bytes itself) to every client (the sequence counts slots, so a stall or a skipped slot shows as a
gap). A client too slow to take its bytes loses whole frames (counted), never half of one; a
frame counts as sent once the kernel has all of it. Faults, from any thread, applied at the next
slot: ``drop_links(down_s)`` closes every client socket, ``stall(s)`` stops sending,
``inject(bytes)`` sends garbage between frames.
"""

from __future__ import annotations

import contextlib
import socket
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from hilrig.drivers.robot_state.wire import RobotState, encode
from hilrig.emulator.outbox import Outbox
from hilrig.emulator.slots import Device, SlotLoop, accept_client

MAX_BACKLOG_BYTES = 64 * 1024  # per client: beyond this, frames are dropped for that client
CLOSE_FLUSH_S = 0.5  # at close, how long a client's unsent frames may take to leave


@dataclass(frozen=True)
class ServerStats:
    """Counters since start."""

    ticks: int  # frames produced (sent to every connected client, if any)
    frames_sent: int  # frames handed whole to client sockets, summed over clients
    frames_dropped: int  # not sent to a slow client, or unsent when its link closed
    clients_accepted: int
    links_dropped: int


class _Client:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.out = Outbox(self._write, MAX_BACKLOG_BYTES)

    def _write(self, data: bytes | bytearray) -> int:
        try:
            return self.sock.send(data)
        except BlockingIOError:
            return 0


class EmulatedRobotStateServer(Device):
    """Streams joint-state frames, one per slot, over TCP to every connected client."""

    thread_name = "robot-state"

    def __init__(
        self,
        source: Callable[[int], RobotState | bytes],
        *,
        rate_hz: float = 1000.0,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        self._source = source
        self.standalone_period_ns = round(1e9 / rate_hz)
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._loop: SlotLoop | None = None
        self._clients: dict[int, _Client] = {}
        self._requests: deque[Callable[[int], None]] = deque()
        self._sequence = 0
        self._stall_until_ns = 0
        self._down_until_ns: int | None = None
        self._garbage = b""
        self._ticks = self._accepted = self._links_dropped = 0
        self._sent_before = self._dropped_before = 0  # by clients since closed

    @property
    def stats(self) -> ServerStats:
        """A snapshot of the counters."""
        clients = list(self._clients.values())
        return ServerStats(
            self._ticks,
            self._sent_before + sum(c.out.frames_sent for c in clients),
            self._dropped_before + sum(c.out.frames_dropped for c in clients),
            self._accepted,
            self._links_dropped,
        )

    def attach(self, loop: SlotLoop) -> None:
        """Accept clients in ``loop`` from now on."""
        self._loop = loop
        loop.watch(self._listener.fileno(), self._accept)

    def tick(self, slot_ns: int) -> None:
        """Apply requested faults, then send this slot's frame to every client."""
        while self._requests:
            self._requests.popleft()(slot_ns)
        if self._down_until_ns is not None and slot_ns >= self._down_until_ns:
            self._down_until_ns = None
            self.attach(self._require_loop())  # connections waiting in the backlog come in
        sequence = self._sequence
        self._sequence += 1
        if slot_ns < self._stall_until_ns or self._down_until_ns is not None:
            return
        state = self._source(sequence)
        frame = state if isinstance(state, bytes) else encode(state)
        self._ticks += 1
        garbage, self._garbage = self._garbage, b""
        for fd, client in list(self._clients.items()):
            try:
                if garbage:
                    client.out.put(garbage, frame=False)
                client.out.put(frame)
            except OSError:
                self._close(fd)

    def close(self) -> None:
        """Give each client's unsent frames a moment to leave, then close every socket."""
        loop = self._require_loop()
        loop.unwatch(self._listener.fileno())
        for client in self._clients.values():
            client.sock.settimeout(CLOSE_FLUSH_S)
            with contextlib.suppress(OSError):
                while client.out.unsent:
                    client.out.flush()
        for fd in list(self._clients):
            self._close(fd)
        self._listener.close()

    # -- faults (any thread) -----------------------------------------------------------------

    def drop_links(self, down_s: float = 0.0) -> None:
        """Close every client connection; for ``down_s`` the robot then stays silent (new
        connections wait in the listen backlog), like a cable pulled and plugged back."""
        self._requests.append(lambda slot_ns: self._drop(slot_ns + round(down_s * 1e9)))

    def stall(self, duration_s: float) -> None:
        """Send nothing for ``duration_s`` (frames of that time are skipped, not queued)."""
        self._requests.append(
            lambda slot_ns: setattr(self, "_stall_until_ns", slot_ns + round(duration_s * 1e9))
        )

    def inject(self, garbage: bytes) -> None:
        """Send ``garbage`` to every client before the next frame."""
        self._requests.append(lambda _: setattr(self, "_garbage", self._garbage + garbage))

    # -- internals (the loop's thread) -------------------------------------------------------

    def _require_loop(self) -> SlotLoop:
        assert self._loop is not None, "not attached to a slot loop"
        return self._loop

    def _drop(self, up_at_ns: int) -> None:
        for fd in list(self._clients):
            self._close(fd)
            self._links_dropped += 1
        self._down_until_ns = up_at_ns
        self._require_loop().unwatch(self._listener.fileno())

    def _accept(self) -> None:
        sock = accept_client(self._listener)
        if sock is None:
            return
        fd = sock.fileno()
        self._clients[fd] = _Client(sock)
        self._accepted += 1
        self._require_loop().watch(fd, lambda: self._read(fd))

    def _read(self, fd: int) -> None:
        """A client sends nothing; readable means it closed (or sent bytes to ignore)."""
        try:
            data = self._clients[fd].sock.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._close(fd)

    def _close(self, fd: int) -> None:
        client = self._clients.pop(fd)
        self._require_loop().unwatch(fd)
        client.out.discard()
        self._sent_before += client.out.frames_sent
        self._dropped_before += client.out.frames_dropped
        client.sock.close()
