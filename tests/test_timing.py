"""The real-time helpers: the CPU wake-up latency request is held exactly while a body runs.

Other processes (a session of a test suite running beside this one) may hold requests of their
own, so the tests look at the limit in force only as an upper bound and count this process's
own open requests."""

import os
import struct

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
