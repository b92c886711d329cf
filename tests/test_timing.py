"""The real-time helpers: the CPU wake-up latency request is held exactly while a body runs;
a frozen heap is out of the collector's reach, after garbage is collected.

Other processes (a session of a test suite running beside this one) may hold requests of their
own, so the tests look at the limit in force only as an upper bound and count this process's
own open requests."""

import os
import struct
import subprocess
import sys
import textwrap

import pytest

from hilrig.timing import CPU_LATENCY_DEVICE, cpu_wakeup_latency, realtime_python


def current_limit_us() -> int:
    """The CPUs' wake-up latency limit in force now (all requests together), us."""
    fd = os.open(CPU_LATENCY_DEVICE, os.O_RDONLY)
    try:
        (value,) = struct.unpack("i", os.read(fd, 4))
    finally:
        os.close(fd)
    return int(value)


def own_requests() -> int:
    """This process's open descriptors on the device (each one a request)."""
    fds = os.listdir("/proc/self/fd")
    return sum(os.path.realpath(f"/proc/self/fd/{fd}") == CPU_LATENCY_DEVICE for fd in fds)


needs_device = pytest.mark.skipif(
    not os.access(CPU_LATENCY_DEVICE, os.R_OK | os.W_OK),
    reason=f"{CPU_LATENCY_DEVICE} needs root",
)


@needs_device
def test_the_request_holds_while_the_body_runs_and_is_withdrawn_after() -> None:
    assert own_requests() == 0
    with cpu_wakeup_latency(50) as held:
        assert held and own_requests() == 1
        assert current_limit_us() <= 50
    assert own_requests() == 0


@needs_device
def test_realtime_python_holds_every_cpu_awake() -> None:
    with realtime_python():
        assert own_requests() == 1
        assert current_limit_us() == 0
    assert own_requests() == 0


def test_without_the_device_nothing_is_held(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("hilrig.timing.CPU_LATENCY_DEVICE", "/nonexistent/cpu_dma_latency")
    with cpu_wakeup_latency() as held:
        assert not held


FREEZE_CHILD = textwrap.dedent(
    """
    import gc, weakref
    from hilrig.timing import freeze_heap

    class Node:
        pass

    kept = [Node() for _ in range(50_000)]  # alive: frozen
    for a, b in zip(kept, kept[1:]):
        a.next, b.prev = b, a
    lost = Node()  # an unreachable cycle: collected, not frozen
    lost.me = lost
    gone = weakref.ref(lost)
    del lost
    tracked = len(gc.get_objects())
    freeze_heap()
    frozen = gc.get_freeze_count()
    print(tracked, frozen, len(gc.get_objects()), gone() is None)
    """
)


def test_freeze_heap_collects_then_freezes_everything_alive() -> None:
    """In a process of its own: the test process's heap stays the collector's."""
    out = subprocess.run(
        [sys.executable, "-c", FREEZE_CHILD], capture_output=True, text=True, check=True
    ).stdout.split()
    tracked, frozen, left, collected = out
    assert collected == "True"  # the cycle was collected first
    assert int(frozen) >= 50_000  # every kept node is frozen
    assert int(left) < int(tracked) // 100  # what a full pass still walks: almost nothing
