"""The Kunwei F/T sensor over a serial port (pyserial), polled from the caller's loop.

``connect()`` opens the port (460800 8N1 by default), sends the start command and waits for the
first frame (blocking, not for the real-time loop). Then the loop selects on ``fileno()`` and
calls ``poll(now_ns)``: one non-blocking read of everything waiting, framed by
:class:`~hilrig.drivers.ft.wire.KunweiFramer`, returned as new samples stamped ``now_ns``
(those read while connecting come first in the first poll). ``poll`` never raises: an error is
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

from hilrig.drivers.base import LinkStatus, RateMeter, Reader, error_text, wait_readable
from hilrig.drivers.ft.wire import (
    START_COMMAND,
    STOP_COMMAND,
    FramerConfig,
    FramerStats,
    FtSample,
    KunweiFramer,
)
from hilrig.drivers.reconnect import Backoff
from hilrig.errors import LinkError

DEFAULT_BAUDRATE = 460800
READ_BYTES = 65536  # per poll: 2340 frames, far more than arrive between two 1 kHz ticks


class FtSerial(Reader[FtSample]):
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
        self._framer = KunweiFramer(framer_config)
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._restart_after_ns = round(restart_after_s * 1e9)
        self._backoff = Backoff(backoff_s)
        self._serial: serial.Serial | None = None
        self._fd = -1
        self._wanted = False  # between connect() and close(): poll reopens a lost link
        self._unreturned: list[FtSample] = []  # read by connect(), returned by the next poll
        self._heard_ns = 0  # the last sample, or the last start command sent
        self._latest: FtSample | None = None
        self._samples = 0
        self._rate = RateMeter()
        self._stalled = False
        self._stalls = 0
        self._reconnects = 0
        self._errors = 0
        self._last_error = ""

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
        while not self._unreturned:
            left_ns = deadline_ns - time.monotonic_ns()
            if left_ns <= 0:
                self.close()
                raise LinkError(
                    f"F/T sensor {self.port}: no valid frame within {first_sample_timeout_s} s "
                    f"of the start command ({self._framer.stats.bytes_in} bytes received)"
                )
            wait_readable(self._fd, left_ns / 1e9)
            self._unreturned = self.poll(time.monotonic_ns())

    def close(self) -> None:
        """Send the stop command and close the port; poll no longer reopens it. Idempotent."""
        self._wanted = False
        self._unreturned = []
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

    def poll(self, now_ns: int) -> list[FtSample]:
        """The samples read now (stamped ``now_ns``), oldest first; never blocks, never raises."""
        try:
            samples = self._pump(now_ns)
        except Exception as err:  # whatever happens (even a bug), the caller's loop carries on
            self._errors += 1
            self._last_error = error_text(err)
            self._drop()
            self._backoff.failed(now_ns)
            samples = []
        if self._unreturned:
            samples, self._unreturned = self._unreturned + samples, []
        return samples

    def latest(self) -> FtSample | None:
        return self._latest

    def status(self) -> LinkStatus:
        latest = self._latest
        age_ns = None if latest is None else time.monotonic_ns() - latest.t_ns
        return LinkStatus(
            endpoint=self.port,
            connected=self.is_connected,
            samples=self._samples,
            rate_hz=self._rate.rate_hz(age_ns),
            age_ns=age_ns,
            stalls=self._stalls,
            reconnects=self._reconnects,
            errors=self._errors,
            last_error=self._last_error,
        )

    def framer_stats(self) -> FramerStats:
        """The framer's counters (frames, rejected, resyncs, bytes dropped) since construction."""
        return self._framer.stats

    def average(
        self,
        duration_s: float = 0.1,
        *,
        timeout_s: float = 1.0,
        on_sample: Callable[[FtSample], None] | None = None,
    ) -> NDArray[np.float64]:
        """Mean raw wrench (6,), N and N*m, of the samples polled over ``duration_s``: to tare.

        Blocks; not for the real-time loop. Every sample read (from the first one a previous
        ``connect`` kept) goes to ``on_sample`` too, so the caller can record it. Raises
        :class:`~hilrig.errors.LinkError` if none arrives within ``max(duration_s, timeout_s)``.
        """
        start_ns = time.monotonic_ns()
        end_ns = start_ns + round(duration_s * 1e9)
        give_up_ns = start_ns + round(max(duration_s, timeout_s) * 1e9)
        wrenches: list[tuple[float, ...]] = []
        while True:
            now_ns = time.monotonic_ns()
            for sample in self.poll(now_ns):
                wrenches.append(sample.wrench_in_sensor)
                if on_sample is not None:
                    on_sample(sample)
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

    def _pump(self, now_ns: int) -> list[FtSample]:
        """Reopen the port when due, read and frame; raises on a lost link."""
        if self._serial is None:
            if not (self._wanted and self._backoff.due(now_ns)):
                return []
            self._open(now_ns)
            self._backoff.succeeded()
            self._reconnects += 1
        try:  # a tty set for timeout 0 reads b"" when empty; a lost one raises (EIO)
            data = os.read(self._fd, READ_BYTES)
        except BlockingIOError:
            data = b""
        latest = self._latest
        if latest is not None and not self._stalled and now_ns - latest.t_ns > self._stall_after_ns:
            self._stalled = True
            self._stalls += 1
        samples = self._framer.feed(data, now_ns) if data else []
        if samples:
            self._latest = samples[-1]
            self._samples += len(samples)
            self._stalled = False
            self._heard_ns = now_ns
            self._rate.update(now_ns, self._samples)
        elif now_ns - self._heard_ns > self._restart_after_ns:
            with contextlib.suppress(BlockingIOError):  # a full output buffer: next time
                os.write(self._fd, START_COMMAND)
            self._heard_ns = now_ns
        return samples
