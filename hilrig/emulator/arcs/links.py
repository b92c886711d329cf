"""The TCP side both ARCS servers share: a listener, its clients and their outboxes in a slot loop.

Non-blocking sockets served by the loop (no thread of their own); each client's replies and
pushes go through an :class:`~hilrig.emulator.outbox.Outbox`, so a client too slow to take its
bytes loses whole frames (counted), never half of one. A subclass says what to do with a new
client (``_greet``) and with its bytes (``_received``); ``drop_all()`` closes every client, as a
pulled cable does.
"""

from __future__ import annotations

import contextlib
import socket

from hilrig.emulator.arcs.wire import FrameDecoder
from hilrig.emulator.outbox import Outbox
from hilrig.emulator.slots import Device, SlotLoop, accept_client

MAX_BACKLOG_BYTES = 64 * 1024  # per client: beyond this, frames are dropped for that client
RECV_BYTES = 65536
CLOSE_FLUSH_S = 0.5  # at close, how long a client's unsent bytes may take to leave


class Link:
    """One client: its socket, outbox and decoder (and what its server keeps of it)."""

    def __init__(self, sock: socket.socket, decoder: FrameDecoder) -> None:
        self.sock = sock
        self.decoder = decoder
        self.out = Outbox(self._write, MAX_BACKLOG_BYTES)
        self.closing = False  # close once the current reply is out

    def _write(self, data: bytes | bytearray) -> int:
        try:
            return self.sock.send(data)
        except BlockingIOError:
            return 0


class LinkServer(Device):
    """A listening socket and its clients in a slot loop; subclasses speak the protocol."""

    def __init__(self, host: str, port: int) -> None:
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._loop: SlotLoop | None = None
        self.links: dict[int, Link] = {}
        self.clients_accepted = 0
        self.links_dropped = 0
        self._sent_before = self._dropped_before = 0  # frames of clients since closed

    def attach(self, loop: SlotLoop) -> None:
        """Accept clients in ``loop`` from now on."""
        self._loop = loop
        loop.watch(self._listener.fileno(), self._accept)

    @property
    def frames_sent(self) -> int:
        """Frames handed whole to client sockets, summed over clients (closed ones too)."""
        return self._sent_before + sum(link.out.frames_sent for link in self.links.values())

    @property
    def frames_dropped(self) -> int:
        """Frames not sent to a slow client, or unsent when its link closed."""
        return self._dropped_before + sum(link.out.frames_dropped for link in self.links.values())

    def close(self) -> None:
        """Give each client's unsent bytes a moment to leave, then close every socket."""
        loop = self._require_loop()
        loop.unwatch(self._listener.fileno())
        for link in self.links.values():
            link.sock.settimeout(CLOSE_FLUSH_S)
            with contextlib.suppress(OSError):
                while link.out.unsent:
                    link.out.flush()
        for fd in list(self.links):
            self._close(fd)
        self._listener.close()

    def drop_all(self) -> None:
        """Close every client connection now (counted as dropped links)."""
        for fd in list(self.links):
            self._close(fd)
            self.links_dropped += 1

    def send(self, fd: int, data: bytes, *, frame: bool = True) -> None:
        """Queue ``data`` to client ``fd`` (a counted frame unless ``frame`` is False); a link
        that fails is closed."""
        try:
            self.links[fd].out.put(data, frame=frame)
        except OSError:
            self._close(fd)

    def flush(self, fd: int) -> None:
        """Write what client ``fd`` has unsent; a link that fails is closed."""
        try:
            self.links[fd].out.flush()
        except OSError:
            self._close(fd)

    # -- for subclasses ----------------------------------------------------------------------

    def _decoder(self) -> FrameDecoder:
        raise NotImplementedError

    def _greet(self, fd: int) -> None:
        """A client has connected (its link is in ``links``)."""

    def _received(self, fd: int, body: bytes) -> None:
        raise NotImplementedError

    # -- internals (the loop's thread) -------------------------------------------------------

    def _require_loop(self) -> SlotLoop:
        assert self._loop is not None, "not attached to a slot loop"
        return self._loop

    def _accept(self) -> None:
        sock = accept_client(self._listener)
        if sock is None:
            return
        fd = sock.fileno()
        self.links[fd] = Link(sock, self._decoder())
        self.clients_accepted += 1
        self._require_loop().watch(fd, lambda: self._read(fd))
        self._greet(fd)

    def _read(self, fd: int) -> None:
        link = self.links.get(fd)
        if link is None:
            return
        try:
            data = link.sock.recv(RECV_BYTES)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._close(fd)
            return
        with contextlib.suppress(OSError):
            link.out.flush()
        for body in link.decoder.feed(data):
            if fd not in self.links:
                return
            self._received(fd, body)
            if link.closing:
                self._close(fd)
                return

    def _close(self, fd: int) -> None:
        link = self.links.pop(fd, None)
        if link is None:
            return
        self._require_loop().unwatch(fd)
        link.out.discard()
        self._sent_before += link.out.frames_sent
        self._dropped_before += link.out.frames_dropped
        link.sock.close()
