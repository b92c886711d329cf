"""The machine's own timing floor: what no 1 kHz loop on it can beat, measured without the loop.

- :func:`wake_ups`: a bare thread under the loop's settings (:func:`hilrig.timing.realtime_python`:
  SCHED_FIFO where granted, 1 us timer slack, idle CPUs held awake, no garbage collection) sleeps
  to absolute deadlines one period apart and, after each wake-up, does the same small numpy work
  (16 products of a 6x6 matrix and a vector, about as long as a tick's compute). Wake-ups over a
  period late bound a session's missed deadlines from below; the work's p99 against its p50 is
  the spread the machine alone puts on a tick.
- :func:`pty_delivery`: a writer thread (as the emulated rig's, SCHED_FIFO 40 where granted)
  sends 4 bytes every period through a link (a pty: the F/T sensor's, whose bytes a kernel
  worker of normal priority hands on; or a socket pair) to a reader in ``select`` (as the loop);
  messages delivered over a period after writing are periods a session would miss.
- :class:`Steal`: the CPU time the hypervisor gave to others meanwhile.

Each returns raw nanoseconds; :func:`timing` summarises them against the period, and
:func:`measure_floor` runs the wake-ups and the pty one after the other, as ``hilrig doctor``.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import HilrigError
from hilrig.timing import realtime_python

PERIOD_NS = 1_000_000
WRITER_PRIORITY = 40  # the emulated rig's thread (hilrig/emulator/slots.py)
CLOCK_TICKS_S = os.sysconf("SC_CLK_TCK")


@dataclass(frozen=True)
class WakeUps:
    """Each wake-up's lateness and the fixed work's time after it (ns), and whether the thread
    ran under SCHED_FIFO."""

    late_ns: NDArray[np.int64]
    work_ns: NDArray[np.int64]
    sched_fifo: bool


@dataclass(frozen=True)
class Timing:
    """Durations summarised (us) against a period: how many, p50, p99, max, and the share over
    a period (%)."""

    count: int
    p50_us: float
    p99_us: float
    max_us: float
    over_a_period_pct: float


def timing(durations_ns: NDArray[np.int64], period_ns: int = PERIOD_NS) -> Timing:
    """``durations_ns`` summarised; the share is of those longer than ``period_ns``."""
    us = durations_ns.astype(np.float64) / 1e3
    p50, p99 = np.percentile(us, [50, 99])
    over = 100 * float(np.count_nonzero(durations_ns > period_ns)) / len(durations_ns)
    return Timing(len(durations_ns), float(p50), float(p99), float(us.max()), over)


def wake_ups(seconds: float, *, cpu: int | None = None, period_ns: int = PERIOD_NS) -> WakeUps:
    """A bare thread's wake-ups to deadlines ``period_ns`` apart for ``seconds``, on ``cpu``
    alone if given (as ``hilrig record --cpu``)."""
    count = max(1, round(seconds * 1e9 / period_ns))
    late = np.zeros(count, dtype=np.int64)
    work = np.zeros(count, dtype=np.int64)
    matrix, vector = np.eye(6) * 0.999, np.ones(6)
    with realtime_python(cpu):
        fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
        deadline = time.monotonic_ns() + period_ns
        for i in range(count):
            remaining = deadline - time.monotonic_ns()
            if remaining > 0:
                time.sleep(remaining / 1e9)
            woke = time.monotonic_ns()
            late[i] = woke - deadline
            product = vector
            for _ in range(16):
                product = matrix @ product
            work[i] = time.monotonic_ns() - woke
            deadline += period_ns
    return WakeUps(late, work, fifo)


def pty_delivery(seconds: float, *, period_ns: int = PERIOD_NS) -> NDArray[np.int64]:
    """Write-to-read delay (ns) of a message every period through a fresh raw pty."""
    write_fd, read_fd = os.openpty()
    tty.setraw(read_fd)
    return delivery(write_fd, read_fd, seconds, period_ns=period_ns)


def delivery(
    write_fd: int, read_fd: int, seconds: float, *, period_ns: int = PERIOD_NS
) -> NDArray[np.int64]:
    """Write-to-read delay (ns) of a 4-byte message written to ``write_fd`` every period for
    ``seconds`` by another thread and read from ``read_fd`` in ``select``; closes both."""
    count = max(1, round(seconds * 1e9 / period_ns))
    sent = np.zeros(count, dtype=np.int64)
    delay = np.zeros(count, dtype=np.int64)
    failed: list[str] = []  # why the writer stopped early

    def write() -> None:
        with contextlib.suppress(OSError):  # not permitted: normal priority
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(WRITER_PRIORITY))
        deadline = time.monotonic_ns() + period_ns
        for i in range(count):
            remaining = deadline - time.monotonic_ns()
            if remaining > 0:
                time.sleep(remaining / 1e9)
            sent[i] = time.monotonic_ns()
            try:
                os.write(write_fd, i.to_bytes(4, "little"))
            except OSError as err:
                failed.append(err.strerror or type(err).__name__)
                return
            deadline += period_ns

    writer = threading.Thread(target=write, name="hilrig-floor-writer")
    received, pending = 0, b""
    try:
        with realtime_python():
            writer.start()
            while received < count:
                readable, _, _ = select.select([read_fd], [], [], 1.0)
                if not readable:
                    if writer.is_alive():
                        continue
                    why = f" (writing: {failed[0]})" if failed else ""
                    raise HilrigError(f"link test: {received} of {count} messages came{why}")
                now = time.monotonic_ns()
                pending += os.read(read_fd, 4096)
                while len(pending) >= 4:
                    i = int.from_bytes(pending[:4], "little")
                    delay[i] = now - sent[i]
                    pending, received = pending[4:], received + 1
    finally:
        writer.join()
        os.close(write_fd)
        os.close(read_fd)
    return delay


@dataclass(frozen=True)
class Floor:
    """The floor measured by :func:`measure_floor`."""

    seconds: float  # of each measurement
    cpu: int | None
    sched_fifo: bool  # whether the waking thread ran under SCHED_FIFO
    wake_ups: Timing  # lateness of a bare thread's wake-ups
    work: Timing  # the fixed work after each wake-up
    pty: Timing  # delay of 1 kHz messages through a pty
    steal_pct: float  # the hypervisor's steal over both, % of CPU time

    @property
    def missed_at_least_pct(self) -> float:
        """The share of periods the machine alone spoils (the larger of the two measured): a
        session here misses about this many of its deadlines at least."""
        return max(self.wake_ups.over_a_period_pct, self.pty.over_a_period_pct)


def measure_floor(seconds: float, *, cpu: int | None = None) -> Floor:
    """A bare thread's 1 kHz wake-ups for ``seconds`` (on ``cpu`` alone if given), then 1 kHz
    messages through a pty for ``seconds``."""
    steal = Steal()
    woken = wake_ups(seconds, cpu=cpu)
    delays = pty_delivery(seconds)
    return Floor(
        seconds=seconds,
        cpu=cpu,
        sched_fifo=woken.sched_fifo,
        wake_ups=timing(woken.late_ns),
        work=timing(woken.work_ns),
        pty=timing(delays),
        steal_pct=steal.percent(),
    )


class Steal:
    """The share of the machine's CPU time the hypervisor gave to others (``steal`` in
    /proc/stat) between construction and ``percent()``: time no thread here could run, however
    high its priority. Summed over all CPUs, in % of (wall time x CPUs); NaN where /proc/stat
    has no steal column."""

    def __init__(self) -> None:
        self._t0_s, self._steal0_s = time.monotonic(), _steal_s()

    def percent(self) -> float:
        elapsed_s = time.monotonic() - self._t0_s
        cpus = os.cpu_count() or 1
        return 100 * (_steal_s() - self._steal0_s) / (elapsed_s * cpus)


def _steal_s() -> float:
    """Steal time of all CPUs so far, s (NaN if not reported)."""
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
    return int(fields[8]) / CLOCK_TICKS_S if len(fields) > 8 else float("nan")
