"""The Kunwei F/T sensor over a serial port (pyserial), polled from the caller's loop.

``connect()`` opens the port (460800 8N1 by default), sends the start command and waits for the
first frame (blocking, not for the real-time loop). Then the loop selects on ``fileno()`` and
calls ``poll(now_ns)``: one non-blocking read(2) of everything waiting, straight into the
framer's buffer and framed by the same compiled call (:class:`~hilrig.drivers.ft.frames.FtFrames`,
the twin of :class:`~hilrig.drivers.ft.wire.KunweiFramer`), returned as rows of
:data:`~hilrig.drivers.ft.wire.SAMPLE_DTYPE` stamped ``now_ns``, in the framer's own array
(valid until the next poll: copy what you keep; those read while connecting come first in the
first poll). ``poll`` never raises: an error is
counted and kept in ``status().last_error``, the port closed and reopened with backoff (and the
start command sent again); after a silence of ``restart_after_s`` the start command is re-sent
(a sensor that rebooted waits for it). ``close()`` sends the stop command. No thread.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable

import numpy as np
import serial
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus, Reader, wait_readable
from hilrig.drivers.ft.frames import FtFrames
from hilrig.drivers.ft.wire import (
    START_COMMAND,
    STOP_COMMAND,
    FramerConfig,
    FramerStats,
)
from hilrig.drivers.reconnect import Backoff
from hilrig.drivers.stream_link import StreamLink
from hilrig.drivers.sys_read import read_error
from hilrig.errors import LinkError

DEFAULT_BAUDRATE = 460800

SampleRows = NDArray[np.void]
"""Rows of SAMPLE_DTYPE: ``t_ns`` (the receive time), ``seq``, ``wrench`` (N, N*m)."""


class FtSerial(StreamLink, Reader[np.void]):
    """A Kunwei sensor on serial port ``port`` (a device path, or a pty path in tests)."""

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        framer_config: FramerConfig | None = None,
        stall_after_s: float = 0.05,
        restart_after_s: float = 0.5,
        backoff_s: tuple[float, float] = (0.05, 1.0),
    ) -> None:
        self.port = port
        self._baudrate = baudrate
        self._framer = FtFrames(framer_config)
        # newest: the newest sample, a row the framer keeps current in place (its fields are
        # views: newest["wrench"][0] is always the newest wrench)
        super().__init__(self._framer.rows, self._framer.newest, Backoff(backoff_s))
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._restart_after_ns = round(restart_after_s * 1e9)
        self._serial: serial.Serial | None = None
        self._fd = -1
        self._wanted = False  # between connect() and close(): poll reopens a lost link
        self._heard_ns = 0  # the last sample, or the last start command sent
        self._stalled = False

    def connect(self, *, first_sample_timeout_s: float | None = 1.0) -> None:
        """Open the port and send start; wait for the first frame unless the timeout is None.

        Raises :class:`~hilrig.errors.LinkError` if the port cannot be opened or no valid frame
        arrives within ``first_sample_timeout_s``.
        """
        if self.is_connected:
            return
        try:
            self._open(time.monotonic_ns())
        except (serial.SerialException, OSError) as err:
            raise LinkError(f"F/T sensor {self.port}: cannot open: {err}") from err
        self._wanted = True
        self._backoff.succeeded()
        if first_sample_timeout_s is None:
            return
        deadline_ns = time.monotonic_ns() + round(first_sample_timeout_s * 1e9)
        while not len(self._unreturned):
            left_ns = deadline_ns - time.monotonic_ns()
            if left_ns <= 0:
                self.close()
                raise LinkError(
                    f"F/T sensor {self.port}: no valid frame within {first_sample_timeout_s} s "
                    f"of the start command ({self._framer.stats.bytes_in} bytes received)"
                )
            wait_readable(self._fd, left_ns / 1e9)
            self._unreturned = self.poll(time.monotonic_ns()).copy()

    def close(self) -> None:
        """Send the stop command and close the port; poll no longer reopens it. Idempotent."""
        self._wanted = False
        self._unreturned = self._none
        if self._serial is not None:
            with contextlib.suppress(OSError):  # if the link is gone the sensor cannot hear us
                os.write(self._fd, STOP_COMMAND)
            self._drop()

    def stop_streaming(self) -> None:
        """Send the stop command but keep the port open, so that poll still reads the frames
        the sensor sent before it (a session's end); poll no longer restarts the stream."""
        self._restart_after_ns = 1 << 62
        if self._serial is not None:
            with contextlib.suppress(OSError):  # if the link is gone the sensor cannot hear us
                os.write(self._fd, STOP_COMMAND)

    @property
    def is_connected(self) -> bool:
        """True while the port is open."""
        return self._serial is not None

    def fileno(self) -> int:
        """The port's descriptor, -1 while it is closed."""
        return self._fd

    def status(self) -> LinkStatus:
        return self._link_status(self.port, self.is_connected)

    def framer_stats(self) -> FramerStats:
        """The framer's counters (frames, rejected, resyncs, bytes dropped) since construction."""
        return self._framer.stats

    def average(
        self,
        duration_s: float = 0.1,
        *,
        timeout_s: float = 1.0,
        on_sample: Callable[[np.void], None] | None = None,
    ) -> NDArray[np.float64]:
        """Mean raw wrench (6,), N and N*m, of the samples polled over ``duration_s``: to tare.

        Blocks; not for the real-time loop. Every sample read (from the first one a previous
        ``connect`` kept) goes to ``on_sample`` too (a copy of its row), so the caller can
        record it. Raises
        :class:`~hilrig.errors.LinkError` if none arrives within ``max(duration_s, timeout_s)``.
        """
        start_ns = time.monotonic_ns()
        end_ns = start_ns + round(duration_s * 1e9)
        give_up_ns = start_ns + round(max(duration_s, timeout_s) * 1e9)
        wrenches: list[list[float]] = []
        while True:
            now_ns = time.monotonic_ns()
            rows = self.poll(now_ns)
            wrenches += rows["wrench"].tolist()
            if on_sample is not None:
                for row in rows:
                    on_sample(row.copy())
            if now_ns >= (end_ns if wrenches else give_up_ns):
                break
            wait_readable(self._fd, ((end_ns if wrenches else give_up_ns) - now_ns) / 1e9)
        if not wrenches:
            raise LinkError(f"F/T sensor {self.port}: no samples to average")
        mean: NDArray[np.float64] = np.array(wrenches, dtype=np.float64).mean(axis=0)
        return mean

    # -- the link ----------------------------------------------------------------------------

    def _open(self, now_ns: int) -> None:
        port = serial.Serial(self.port, self._baudrate, timeout=0)
        self._serial, self._fd = port, port.fileno()
        self._framer.reset()
        self._heard_ns = now_ns
        os.write(self._fd, START_COMMAND)

    def _drop(self) -> None:
        port, self._serial, self._fd = self._serial, None, -1
        if port is not None:
            with contextlib.suppress(Exception):  # a broken port may fail to close too
                port.close()

    def _pump(self, now_ns: int) -> SampleRows:
        """Reopen the port when due, read and frame; raises on a lost link."""
        if self._serial is None:
            if not (self._wanted and self._backoff.due(now_ns)):
                return self._none
            self._open(now_ns)
            self._backoff.succeeded()
            self.reconnects += 1
        framer = self._framer
        # read(2) and framing in one compiled call; a tty set for timeout 0 reads nothing when
        # empty, as a hung-up one does (the start command re-sent after a silence then fails)
        n = framer.receive(self._fd, now_ns)
        if not n and (error := read_error(framer.last_read)) is not None:
            raise error
        latest_ns = self._latest_t_ns
        if latest_ns >= 0 and not self._stalled and now_ns - latest_ns > self._stall_after_ns:
            self._stalled = True
            self.stalls += 1
        if n:
            self._received(now_ns, n)
            self._stalled = False
            self._heard_ns = now_ns
        elif now_ns - self._heard_ns > self._restart_after_ns:
            with contextlib.suppress(BlockingIOError):  # a full output buffer: next time
                os.write(self._fd, START_COMMAND)
            self._heard_ns = now_ns
        return framer.rows[:n] if n else self._none
