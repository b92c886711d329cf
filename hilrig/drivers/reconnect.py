"""Reopening lost links without a thread: when to try (backoff) and a non-blocking TCP connect.

Shared by every polled driver. It only answers "is an attempt due at ``now_ns``?": the driver
makes the (non-blocking) attempt itself from its ``poll``, so no thread and no sleep is needed.
A retry library such as tenacity wraps a blocking call in a sleeping loop, which is what the
polled drivers must not do; the policy itself is a few lines. A TCP connect to a real robot
can take long, so it is started non-blocking (``connect_ex``) and its completion checked by the
next polls (``tcp_connected``).
"""

from __future__ import annotations

import errno
import os
import select
import socket

from hilrig.errors import LinkError, ParameterError


class Backoff:
    """Attempt times after failures: ``min_s``, then doubling up to ``max_s``; reset on success."""

    def __init__(self, bounds_s: tuple[float, float] = (0.01, 1.0), *, factor: float = 2.0) -> None:
        min_s, max_s = bounds_s
        if not 0.0 < min_s <= max_s or factor < 1.0:
            raise ParameterError(f"backoff needs 0 < min <= max and factor >= 1, got {bounds_s}")
        self._min_ns = round(min_s * 1e9)
        self._max_ns = round(max_s * 1e9)
        self._factor = factor
        self._delay_ns = self._min_ns
        self.next_attempt_ns = 0  # 0: an attempt may be made now

    @property
    def delay_s(self) -> float:
        """The wait that the next failure will schedule."""
        return self._delay_ns / 1e9

    def due(self, now_ns: int) -> bool:
        """True when an attempt may be made at ``now_ns``."""
        return now_ns >= self.next_attempt_ns

    def failed(self, now_ns: int) -> None:
        """A link was lost or an attempt failed at ``now_ns``: wait, then wait longer next time."""
        self.next_attempt_ns = now_ns + self._delay_ns
        self._delay_ns = min(round(self._delay_ns * self._factor), self._max_ns)

    def succeeded(self) -> None:
        """The link is up: the next loss waits ``min_s`` again."""
        self._delay_ns = self._min_ns
        self.next_attempt_ns = 0


def start_tcp_connect(address: tuple[str, int]) -> socket.socket:
    """A non-blocking TCP_NODELAY socket whose connect to ``address`` is under way (or done).

    Raises LinkError if it failed at once. ``address`` should be numeric: a host name is
    resolved here, blocking.
    """
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setblocking(False)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    code = sock.connect_ex(address)
    if code not in (0, errno.EINPROGRESS):
        sock.close()
        raise LinkError(f"TCP connect failed: {os.strerror(code)}")
    return sock


def tcp_connected(sock: socket.socket) -> bool:
    """Whether the connect under way on ``sock`` finished (never blocks); LinkError if it failed."""
    _, writable, _ = select.select([], [sock], [], 0)
    if not writable:
        return False
    code = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
    if code:
        raise LinkError(f"TCP connect failed: {os.strerror(code)}")
    return True
