"""Robot joint state over TCP, polled from the caller's loop; reconnects on loss.

Follows the driver shape of ``hilrig.drivers.base``: the loop selects on ``fileno()`` and calls
``poll(now_ns)``, which takes what is waiting on the non-blocking socket straight into the
decoder's buffer (TCP_NODELAY; up to 385 frames a poll, the rest at the next; the compiled
decoder reads and decodes in one call, read(2) included, any other takes a ``recv_into``) and
returns the frames decoded, rows of :data:`~hilrig.drivers.robot_state.wire.STATE_DTYPE`
stamped ``now_ns`` in the decoder's own array (valid until the next poll: copy what you keep).
``latest()`` is the newest row and ``status().age_ns`` tells how old it is, which the loop
compares with its limit to hold the robot on a lost link. The decoder is pluggable
(``decoder_factory``, default the compiled :class:`~hilrig.drivers.robot_state.frames.StateFrames`)
so a real controller's format can replace hilrig's. ``poll`` never raises: each error is
counted, the last kept in ``last_error``, and the link reopened with backoff. Connecting is
non-blocking too (``connect_ex``, then writability checked by the next polls): no thread ever.
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus, Reader, wait_readable
from hilrig.drivers.compiled_decoder import CompiledDecoder
from hilrig.drivers.reconnect import Backoff, start_tcp_connect, tcp_connected
from hilrig.drivers.robot_state.frames import StateFrames
from hilrig.drivers.robot_state.wire import DecoderStats
from hilrig.drivers.stream_link import StreamLink
from hilrig.drivers.sys_read import BYTES_READ, read_error
from hilrig.errors import LinkError

StateRows = NDArray[np.void]
"""Rows of STATE_DTYPE: ``t_ns`` (the receive time), ``device_t_ns``, ``seq``, ``q``, ``qd``,
``tau``, ``status``."""


class StateDecoder(Protocol):
    """Turns received bytes into rows of STATE_DTYPE; counts what it drops (as StateFrames)."""

    rows: StateRows
    newest: StateRows

    @property
    def free(self) -> memoryview:
        """Where the next bytes are received."""
        ...

    def feed(self, count: int, t_ns: int) -> int:
        """Decode the ``count`` bytes received into ``free``; the frames are ``rows[:n]``, each
        stamped ``t_ns``, and the last of them is copied into ``newest`` (the loop judges the
        link's freshness from its ``t_ns``)."""
        ...

    @property
    def stats(self) -> DecoderStats: ...

    def reset(self) -> None: ...


class RobotStateClient(StreamLink, Reader[np.void]):
    """Reads the joint-state stream at ``host:port``; ``with client:`` connects and closes."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        decoder_factory: Callable[[], StateDecoder] = StateFrames,
        connect_timeout_s: float = 1.0,
        stall_after_s: float = 0.05,
        backoff_s: tuple[float, float] = (0.01, 1.0),
    ) -> None:
        self.endpoint = (host, port)
        self._decoder = decoder = decoder_factory()
        self._compiled = decoder if isinstance(decoder, CompiledDecoder) else None
        # newest: the newest frame, a row the decoder keeps current in place (its fields are
        # views: newest["q"][0] is always the newest q)
        super().__init__(decoder.rows, decoder.newest, Backoff(backoff_s))
        self._connect_timeout_ns = round(connect_timeout_s * 1e9)
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._sock: socket.socket | None = None  # connecting or connected
        self._fd = -1  # the socket's once connected
        self._connect_started_ns = 0
        self._wanted = False  # between connect() and close(): poll reopens a lost link
        self._linked_before = False
        self._bytes_fed = 0  # received for a decoder that is not compiled

    @property
    def bytes_received(self) -> int:
        """Bytes received since construction."""
        compiled = self._compiled
        return self._bytes_fed + (0 if compiled is None else int(compiled.io[BYTES_READ]))

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
        self._unreturned = self.poll(time.monotonic_ns()).copy()
        if first_frame_timeout_s is None:
            return
        deadline_ns = time.monotonic_ns() + round(first_frame_timeout_s * 1e9)
        while not len(self._unreturned):
            left_ns = deadline_ns - time.monotonic_ns()
            if left_ns <= 0:
                self.close()
                raise LinkError(
                    f"robot state {self._where()}: no valid frame within {first_frame_timeout_s}"
                    f" s ({self.last_error or 'nothing received'})"
                )
            wait_readable(self._fd, left_ns / 1e9)
            self._unreturned = self.poll(time.monotonic_ns()).copy()

    def close(self) -> None:
        """Close the socket; poll no longer reopens it. Idempotent."""
        self._wanted = False
        self._unreturned = self._none
        self._drop()

    @property
    def is_connected(self) -> bool:
        """True while the socket is connected."""
        return self._fd >= 0

    def fileno(self) -> int:
        """The connected socket's descriptor; -1 while down or still connecting."""
        return self._fd

    def status(self) -> LinkStatus:
        return self._link_status(self._where(), self.is_connected)

    # -- the link ----------------------------------------------------------------------------

    def _pump(self, now_ns: int) -> StateRows:
        """Connect when due, then read and decode; raises on a lost link."""
        if self._sock is None:
            if not (self._wanted and self._backoff.due(now_ns)):
                return self._none
            self._sock = start_tcp_connect(self.endpoint)
            self._connect_started_ns = now_ns
        if self._fd < 0 and not self._connected(now_ns):
            return self._none
        n = self._receive(now_ns)
        if not n:
            return self._none
        if self._latest_t_ns >= 0 and now_ns - self._latest_t_ns > self._stall_after_ns:
            self.stalls += 1
        self._received(now_ns, n)
        return self._decoder.rows[:n]

    def _receive(self, now_ns: int) -> int:
        """Read what waits and decode it (one compiled call for a compiled decoder); the frames
        completed. Raises on a lost link."""
        compiled = self._compiled
        if compiled is not None:
            n = compiled.receive(self._fd, now_ns)
            if n:
                return n
            count = compiled.last_read
            if (error := read_error(count)) is not None:
                raise error
        else:
            assert self._sock is not None
            try:
                count = self._sock.recv_into(self._decoder.free)
            except BlockingIOError:
                return 0
            self._bytes_fed += count
            if count:
                return self._decoder.feed(count, now_ns)
        if count == 0:
            raise LinkError(f"robot state {self._where()}: closed by the robot")
        return 0

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
