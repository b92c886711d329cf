"""The Kunwei F/T sensor over a serial port (pyserial): a reader thread keeping the newest sample.

``connect()`` opens the port (460800 8N1 by default), sends the start command and starts a
daemon reader thread; ``latest()`` returns the newest :class:`~hilrig.drivers.ft_sensor.FtSample`
without blocking and ``drain()`` every sample since the last drain (for recording). No exception
escapes the thread: each is counted and kept in ``status().last_error``; on a lost link the
thread reopens the port with exponential backoff and sends the start command again, and after a
silence of ``restart_after_s`` it re-sends the start command (a sensor that rebooted waits for
it). ``close()`` sends the stop command and joins the thread.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque

import numpy as np
import serial
from numpy.typing import NDArray

from hilrig.drivers.base import LinkStatus, Reader
from hilrig.drivers.ft_sensor import (
    START_COMMAND,
    STOP_COMMAND,
    FramerConfig,
    FramerStats,
    FtSample,
    KunweiFramer,
)
from hilrig.errors import LinkError

DEFAULT_BAUDRATE = 460800
HISTORY = 4096  # samples kept for drain(): 4 s at 1 kHz
_RATE_WINDOW_NS = 500_000_000


class FtSerial(Reader[FtSample]):
    """A Kunwei sensor on serial port ``port`` (a device path, or a pty path in tests)."""

    def __init__(
        self,
        port: str,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        framer_config: FramerConfig | None = None,
        read_timeout_s: float = 0.02,
        stall_after_s: float = 0.05,
        restart_after_s: float = 0.5,
        backoff_s: tuple[float, float] = (0.05, 1.0),
    ) -> None:
        self.port = port
        self._baudrate = baudrate
        self._framer = KunweiFramer(framer_config)
        self._read_timeout_s = read_timeout_s
        self._stall_after_ns = round(stall_after_s * 1e9)
        self._restart_after_ns = round(restart_after_s * 1e9)
        self._backoff_s = backoff_s
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._first_sample = threading.Event()
        self._latest: FtSample | None = None
        self._history: deque[FtSample] = deque(maxlen=HISTORY)
        self._samples = 0
        self._rate_hz = 0.0
        self._rate_t0_ns = 0
        self._rate_n0 = 0
        self._stalled = False
        self._stalls = 0
        self._reconnects = 0
        self._errors = 0
        self._last_error = ""

    # -- Reader ------------------------------------------------------------------------------

    def connect(self, *, first_sample_timeout_s: float | None = 1.0) -> None:
        """Open the port, send start, start the reader; wait for the first frame if asked.

        Raises :class:`~hilrig.errors.LinkError` if the port cannot be opened or no valid frame
        arrives within ``first_sample_timeout_s`` (None: do not wait).
        """
        if self.is_connected:
            return
        try:
            self._serial = self._open()
        except (serial.SerialException, OSError) as err:
            raise LinkError(f"F/T sensor {self.port}: cannot open: {err}") from err
        self._stop.clear()
        self._first_sample.clear()
        self._thread = threading.Thread(target=self._run, daemon=True, name=f"ft {self.port}")
        self._thread.start()
        if first_sample_timeout_s is not None and not self._first_sample.wait(
            first_sample_timeout_s
        ):
            self.close()
            raise LinkError(
                f"F/T sensor {self.port}: no valid frame within {first_sample_timeout_s} s "
                f"of the start command ({self._framer.stats.bytes_in} bytes received)"
            )

    def close(self) -> None:
        """Stop the reader (joined), send the stop command and close the port. Idempotent."""
        self._stop.set()
        port = self._serial
        if port is not None:
            # the reader may have closed it already: then there is nothing to wake
            with contextlib.suppress(serial.SerialException, OSError, TypeError):
                port.cancel_read()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        port = self._serial
        self._serial = None
        if port is not None:
            # if the link is gone the sensor cannot hear us anyway
            with contextlib.suppress(serial.SerialException, OSError):
                port.write(STOP_COMMAND)
            port.close()

    @property
    def is_connected(self) -> bool:
        """True while the reader runs and the port is open."""
        return self._thread is not None and self._thread.is_alive() and self._serial is not None

    def latest(self) -> FtSample | None:
        return self._latest

    def drain(self) -> list[FtSample]:
        """Samples since the last drain, oldest first (at most the last ``HISTORY``)."""
        history = self._history
        return [history.popleft() for _ in range(len(history))]

    def status(self) -> LinkStatus:
        latest = self._latest
        age_ns = None if latest is None else time.monotonic_ns() - latest.t_ns
        silent = age_ns is None or age_ns > 2 * _RATE_WINDOW_NS
        return LinkStatus(
            endpoint=self.port,
            connected=self.is_connected,
            samples=self._samples,
            rate_hz=0.0 if silent else self._rate_hz,
            age_ns=age_ns,
            stalls=self._stalls,
            reconnects=self._reconnects,
            errors=self._errors,
            last_error=self._last_error,
        )

    def framer_stats(self) -> FramerStats:
        """The framer's counters (frames, rejected, resyncs, bytes dropped) since construction."""
        return self._framer.stats

    def average(self, duration_s: float = 0.1, *, timeout_s: float = 1.0) -> NDArray[np.float64]:
        """Mean raw wrench (6,), N and N*m, over the next ``duration_s``: the reading to tare.

        Blocks; not for the real-time loop. Raises :class:`~hilrig.errors.LinkError` if no
        sample arrives within ``max(duration_s, timeout_s)``.
        """
        self.drain()
        deadline = time.monotonic() + max(duration_s, timeout_s)
        time.sleep(duration_s)
        samples = self.drain()
        while not samples and time.monotonic() < deadline:
            time.sleep(0.005)
            samples = self.drain()
        if not samples:
            raise LinkError(f"F/T sensor {self.port}: no samples to average")
        wrenches = np.array([s.wrench_in_sensor for s in samples], dtype=np.float64)
        mean: NDArray[np.float64] = wrenches.mean(axis=0)
        return mean

    # -- the reader thread -------------------------------------------------------------------

    def _open(self) -> serial.Serial:
        port = serial.Serial(self.port, self._baudrate, timeout=self._read_timeout_s)
        self._framer.reset()
        port.write(START_COMMAND)
        return port

    def _run(self) -> None:
        delay_s = self._backoff_s[0]
        while not self._stop.is_set():
            port = self._serial
            try:
                if port is None:
                    port = self._serial = self._open()
                    self._reconnects += 1
                    delay_s = self._backoff_s[0]
                self._pump(port)
            except Exception as err:  # whatever happens (even a bug), the thread carries on
                self._errors += 1
                self._last_error = f"{type(err).__name__}: {err}"
                if port is not None:
                    self._serial = None
                    with contextlib.suppress(Exception):  # a broken port may fail to close too
                        port.close()
                self._stop.wait(delay_s)
                delay_s = min(2 * delay_s, self._backoff_s[1])

    def _pump(self, port: serial.Serial) -> None:
        """Read and frame until stopped; raises on a lost link."""
        framer = self._framer
        silent_since_ns = time.monotonic_ns()
        while not self._stop.is_set():
            waiting = port.in_waiting
            data = port.read(waiting if waiting else 1)
            now = time.monotonic_ns()
            samples = framer.feed(data, now) if data else None
            if samples:
                self._publish(samples, now)
                silent_since_ns = now
            elif now - silent_since_ns > self._restart_after_ns:
                port.write(START_COMMAND)
                silent_since_ns = now
            latest = self._latest
            if (
                latest is not None
                and not self._stalled
                and now - latest.t_ns > self._stall_after_ns
            ):
                self._stalled = True
                self._stalls += 1

    def _publish(self, samples: list[FtSample], now: int) -> None:
        self._history.extend(samples)
        self._latest = samples[-1]
        self._samples += len(samples)
        self._stalled = False
        if now - self._rate_t0_ns >= _RATE_WINDOW_NS:
            if self._rate_t0_ns:
                self._rate_hz = (self._samples - self._rate_n0) * 1e9 / (now - self._rate_t0_ns)
            self._rate_t0_ns = now
            self._rate_n0 = self._samples
        self._first_sample.set()
