"""The real-time loop's thread settings, latency histograms that never allocate, and compiled
kernels called without dispatch.

:func:`realtime_python` runs a block without cyclic garbage collection, with 1 us timer slack
(Linux prctl: sleeps and ``select`` wake within a few microseconds of their target instead of the
default 50 us), under SCHED_FIFO where permitted, and with the CPUs kept out of slow idle states
(:func:`cpu_wakeup_latency`) where permitted. :class:`LatencyHistogram` counts durations in
1 us bins; its add is one compiled call (a Python-level add, with its numpy item update, took
4-5 us on a slow machine, and the loop adds six a tick). :func:`bound_kernel` calls a compiled
kernel without numba's per-call dispatch. :func:`freeze_heap` keeps the collector's full passes
short in the rig's other processes.
"""

from __future__ import annotations

import contextlib
import gc
import os
import struct
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numba import typeof
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.errors import HilrigError
from hilrig.libc import linux_libc

PR_SET_TIMERSLACK = 29
CPU_LATENCY_DEVICE = "/dev/cpu_dma_latency"  # Linux PM QoS: the CPUs' largest wake-up latency
CPUIDLE_DRIVER = "/sys/devices/system/cpu/cpuidle/current_driver"
# An idle spinner: pinned, SCHED_IDLE, killed with its parent (prctl PR_SET_PDEATHSIG, SIGKILL)
SPINNER = (
    "import ctypes, os\n"
    "ctypes.CDLL(None).prctl(1, 9)\n"
    "if os.getppid() != {parent}: raise SystemExit\n"
    "os.sched_setaffinity(0, {{{cpu}}})\n"
    "os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))\n"
    "while True: pass\n"
)
REALTIME_PRIORITY = 50  # SCHED_FIFO, below the kernel's own threads (99) and IRQ threads (50+)


def tighten_timer_slack(slack_ns: int = 1000) -> bool:
    """Ask Linux to wake this thread's sleeps within ``slack_ns``; False where unsupported."""
    libc = linux_libc()
    if libc is None:
        return False
    return bool(libc.prctl(PR_SET_TIMERSLACK, slack_ns, 0, 0, 0) == 0)


def freeze_heap() -> None:
    """Collect once, then put every object alive now out of the cyclic collector's reach
    (``gc.freeze``): its later passes walk only what was made afterwards. A long-lived process
    calls it when its set-up is done. A full pass over the ~120,000 objects of the emulated rig's
    imports took 25 ms here: in the rig's one thread such a pass stopped both of its streams
    (docs/rig-timing.md). Freezing is constant time; counting the frozen (``gc.get_freeze_count``)
    walks them all, 15 ms over a session's ~210,000 just before its first tick, so it is not
    done here."""
    gc.collect()
    gc.freeze()


@contextmanager
def realtime_python(cpu: int | None = None) -> Iterator[None]:
    """Run the body as real-time as CPython allows, and restore everything after.

    No cyclic garbage collection (what is alive now is frozen out of it after one collection,
    and the tick allocates nothing that needs it), so no collector pause of several ms lands on
    a tick; 1 us timer slack for this thread's sleeps (Linux); and SCHED_FIFO for this thread
    where permitted; and every CPU kept out of idle states slower to leave than 0 us while the
    body runs (:func:`cpu_wakeup_latency`, root only; idle spinners where the kernel has no idle
    driver); and this thread on ``cpu`` alone when one is given (:func:`on_cpu`). A shorter GIL
    switch interval was measured too (0.2 ms against the default 5 ms) and brought no gain.
    """
    enabled = gc.isenabled()
    freeze_heap()
    gc.disable()
    tighten_timer_slack()
    try:
        # first: its spinners must not inherit SCHED_FIFO, nor one CPU (one spinner per CPU)
        with cpu_wakeup_latency(), on_cpu(cpu):
            policy = raise_priority()
            try:
                yield
            finally:
                if policy is not None:
                    os.sched_setscheduler(0, *policy)
    finally:
        gc.unfreeze()
        if enabled:
            gc.enable()


@contextmanager
def on_cpu(cpu: int | None) -> Iterator[None]:
    """Run the body with this thread on ``cpu`` alone (``None``: wherever the OS puts it), then
    let it run where it could before. Raises HilrigError (one line) if it may not run there.

    For a CPU kept free for the loop (Linux ``isolcpus``, a cpuset), as ``cyclictest -a`` or
    ros2_control's ``cpu_affinity`` do. Only this thread moves: processes started from it
    meanwhile inherit the one CPU, so a session starts its children before."""
    if cpu is None:
        yield
        return
    previous = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, {cpu})
    except (OSError, ValueError, OverflowError) as err:
        reason = err.strerror if isinstance(err, OSError) else str(err)
        runs_on = ", ".join(str(c) for c in sorted(previous))
        raise HilrigError(
            f"cpu {cpu}: the loop's thread may not run there ({reason}); it may run on {runs_on}"
        ) from None
    try:
        yield
    finally:
        os.sched_setaffinity(0, previous)


def check_cpu(cpu: int | None) -> None:
    """Raise HilrigError (one line) unless this thread may run on ``cpu`` (tried, then undone)."""
    with on_cpu(cpu):
        pass


@contextmanager
def cpu_wakeup_latency(max_us: int = 0) -> Iterator[bool]:
    """Keep every CPU out of idle states that take longer than ``max_us`` to leave while the body
    runs (a Linux PM QoS request on /dev/cpu_dma_latency, held open, as cyclictest does); yields
    whether the request holds (root only: elsewhere nothing changes).

    An idle CPU then polls instead of halting. On a virtual machine a halted vCPU leaves the
    guest and waits for the host to wake it: measured here, a 1 kHz thread's wake-ups were over
    a period late 0.013-0.15 % of the time halting and 0-0.007 % polling (p99 128-144 against
    36-54 us). Where the kernel has no idle driver (``cpuidle`` says ``none``, as in a Firecracker
    microVM) an idle CPU always halts and the request changes nothing; for ``max_us`` 0 it is
    then kept by :func:`idle_spinners`. The cost: idle CPUs burn power (the host's CPU time)
    while it holds.
    """
    try:
        fd = os.open(CPU_LATENCY_DEVICE, os.O_WRONLY)
    except OSError:  # no such device, or not permitted
        yield False
        return
    try:
        try:
            os.write(fd, struct.pack("i", max_us))
        except OSError:
            yield False
        else:
            spin = max_us == 0 and idle_driver() == "none"
            with idle_spinners() if spin else contextlib.nullcontext():
                yield True
    finally:
        os.close(fd)  # closing withdraws the request


def idle_driver() -> str:
    """The kernel's cpuidle driver (``none`` when it has none; ``""`` when not Linux)."""
    try:
        return Path(CPUIDLE_DRIVER).read_text().strip()
    except OSError:
        return ""


@contextmanager
def idle_spinners() -> Iterator[list[int]]:
    """One process per CPU, pinned to it, spinning at ``SCHED_IDLE`` (the lowest priority, below
    every normal and real-time thread) while the body runs; yields their pids.

    A CPU that runs a spinner never halts, so a thread woken on it starts at once, on warm
    caches, as under a polling idle driver. Measured by hand on a Firecracker microVM without
    one (docs/rig-timing.md): 30 s sessions at 1 kHz missed 6.7 / 4.8 % of their deadlines with
    spinners against 31.0 / 36.1 % without, and a bare thread's short work after a wake-up took
    half as long. The spinners die with this process (parent-death signal) and end with the body.
    """
    spinners: list[subprocess.Popen[bytes]] = []
    try:
        for cpu in sorted(os.sched_getaffinity(0)):
            code = SPINNER.format(cpu=cpu, parent=os.getpid())
            spinners.append(subprocess.Popen([sys.executable, "-S", "-c", code]))
        yield [spinner.pid for spinner in spinners]
    finally:
        for spinner in spinners:
            spinner.kill()
        for spinner in spinners:
            spinner.wait()


def raise_priority(priority: int = REALTIME_PRIORITY) -> tuple[int, os.sched_param] | None:
    """Run this thread under SCHED_FIFO at ``priority`` where the OS allows it (root or
    CAP_SYS_NICE), so other processes on a busy machine cannot preempt it for a whole scheduler
    slice. Returns the previous (policy, param) to restore, or None if not allowed."""
    if not hasattr(os, "sched_setscheduler"):
        return None
    previous = (os.sched_getscheduler(0), os.sched_getparam(0))
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError:  # not permitted: run at normal priority
        return None
    return previous


def realtime_permitted() -> bool:
    """Whether this process may run threads under SCHED_FIFO (root, CAP_SYS_NICE or an
    RLIMIT_RTPRIO): tried on this thread at priority 1 and undone."""
    previous = raise_priority(1)
    if previous is None:
        return False
    os.sched_setscheduler(0, *previous)
    return True


def bound_kernel(kernel: Any, *arrays: Any, last: tuple[Any, ...]) -> Callable[..., Any]:
    """``kernel`` (a numba ``@njit`` function) with its leading ``arrays`` bound, calling the
    machine code compiled for exactly their types and those of the example trailing arguments
    ``last`` (compiled or loaded from the cache now).

    numba's dispatcher types every argument on every call (about 0.3 us each here, more for
    record arrays); the bound call skips that. It also skips the checks: the caller must pass
    trailing arguments of the types of ``last`` (Python ints and floats), and the bound arrays
    must stay the ones bound (keep references; never rebind them).
    """
    signature = tuple(typeof(value) for value in (*arrays, *last))  # type: ignore[no-untyped-call]
    entry: Callable[..., Any] = kernel.compile(signature)
    return partial(entry, *arrays)


COUNT, TOTAL_NS, MAX_NS = range(3)  # entries of a histogram's totals


@njit(cache=True)
def add_duration(counts: NDArray[np.int64], totals: NDArray[np.int64], duration_ns: int) -> None:
    """Count ``duration_ns`` in its 1 us bin (negative in bin 0, beyond the last in the last)."""
    last = counts.shape[0] - 1
    bin_us = duration_ns // 1000
    counts[min(max(bin_us, 0), last)] += 1
    totals[COUNT] += 1
    totals[TOTAL_NS] += duration_ns
    if duration_ns > totals[MAX_NS]:
        totals[MAX_NS] = duration_ns


class LatencyHistogram:
    """Counts of durations in 1 us bins up to ``max_us`` (longer ones in the last bin, exact max).

    ``add(duration_ns)`` (an int) is O(1), compiled, and allocates nothing; quantiles are exact
    to the microsecond.
    """

    def __init__(self, max_us: int = 20_000) -> None:
        self._counts = np.zeros(max_us + 1, dtype=np.int64)
        self._totals = np.zeros(3, dtype=np.int64)
        self._bind()

    def _bind(self) -> None:
        self.add: Callable[[int], None] = bound_kernel(
            add_duration, self._counts, self._totals, last=(0,)
        )

    def __getstate__(self) -> dict[str, Any]:
        return {"counts": self._counts, "totals": self._totals}  # the bound call is not data

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._counts, self._totals = state["counts"], state["totals"]
        self._bind()

    @property
    def count(self) -> int:
        return int(self._totals[COUNT])

    @property
    def total_ns(self) -> int:
        return int(self._totals[TOTAL_NS])

    @property
    def max_ns(self) -> int:
        """The longest duration added (0 before any positive one)."""
        return int(self._totals[MAX_NS])

    def quantile_us(self, q: float) -> float:
        """The q-quantile (0..1) in us, to the bin (NaN when empty)."""
        count = self.count
        if count == 0:
            return float("nan")
        cumulative = np.cumsum(self._counts)
        return float(np.searchsorted(cumulative, q * count, side="left"))

    def summary_us(self) -> dict[str, float]:
        """Mean, p50, p99, p99.9 and max, us."""
        count = self.count
        mean = self.total_ns / count / 1000 if count else float("nan")
        return {
            "mean": mean,
            "p50": self.quantile_us(0.5),
            "p99": self.quantile_us(0.99),
            "p99.9": self.quantile_us(0.999),
            "max": self.max_ns / 1000,
        }

    @property
    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The bin counts and the totals :func:`add_duration` adds to (the arrays themselves)."""
        return self._counts, self._totals

    def counts(self) -> NDArray[np.int64]:
        """The bin counts (a copy), bin i = [i, i+1) us."""
        return self._counts.copy()
