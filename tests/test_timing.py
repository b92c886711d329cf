"""The real-time helpers: the CPU wake-up latency request is held exactly while a body runs, with
idle spinners (one per CPU, dying with their parent) where the kernel has no idle driver; a
frozen heap is out of the collector's reach, after garbage is collected.

Other processes (a session of a test suite running beside this one) may hold requests of their
own, so the tests look at the limit in force only as an upper bound and count this process's
own open requests."""

import os
import struct
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from hilrig.timing import (
    CPU_LATENCY_DEVICE,
    cpu_wakeup_latency,
    idle_spinners,
    realtime_permitted,
    realtime_python,
)


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


SCHED_IDLE_POLICY = 5  # /proc/PID/stat field 41


def policy_and_cpus(pid: int) -> tuple[int, set[int]] | None:
    """A live process's scheduling policy and allowed CPUs (None once it is gone or a zombie)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        if stat[0] == "Z":
            return None
        return int(stat[38]), os.sched_getaffinity(pid)
    except (OSError, ProcessLookupError):
        return None


def eventually(predicate: Callable[[], bool], what: str, timeout_s: float = 60.0) -> None:
    """Wait until ``predicate()`` (a bound against a hang, not a timing assertion)."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


def test_one_idle_spinner_per_cpu_while_the_body_runs_and_none_after() -> None:
    cpus = sorted(os.sched_getaffinity(0))
    with idle_spinners() as pids:
        assert len(pids) == len(cpus)
        expected = [(SCHED_IDLE_POLICY, {cpu}) for cpu in cpus]  # pinned, each to its CPU
        eventually(lambda: [policy_and_cpus(pid) for pid in pids] == expected, "spinners set")
    assert [policy_and_cpus(pid) for pid in pids] == [None] * len(cpus)


SPINNING_CHILD = textwrap.dedent(
    """
    import time
    from hilrig.timing import idle_spinners

    with idle_spinners() as pids:
        print(*pids, flush=True)
        time.sleep(600)
    """
)


def test_the_spinners_die_with_their_parent() -> None:
    parent = subprocess.Popen([sys.executable, "-c", SPINNING_CHILD], stdout=subprocess.PIPE)
    assert parent.stdout is not None
    pids = [int(pid) for pid in parent.stdout.readline().split()]
    assert len(pids) == len(os.sched_getaffinity(0))
    eventually(lambda: all(policy_and_cpus(pid) for pid in pids), "spinners started")
    parent.kill()  # SIGKILL: no finally runs in the parent
    parent.wait()
    eventually(lambda: not any(policy_and_cpus(pid) for pid in pids), "spinners left running")


@needs_device
@pytest.mark.parametrize(("driver", "spinners"), [("none", True), ("haltpoll", False)])
def test_the_request_spins_the_cpus_only_where_no_idle_driver_can_keep_them_awake(
    driver: str, spinners: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "driver").write_text(f"{driver}\n")
    monkeypatch.setattr("hilrig.timing.CPUIDLE_DRIVER", str(tmp_path / "driver"))
    before = children()  # e.g. multiprocessing's resource tracker, started by earlier tests
    with cpu_wakeup_latency() as held:
        assert held and len(children() - before) == (
            len(os.sched_getaffinity(0)) if spinners else 0
        )
    with cpu_wakeup_latency(50):  # a request that idle states may still meet: no spinners
        assert children() == before


def children() -> set[str]:
    """This process's child processes now."""
    me = os.getpid()
    return set(Path(f"/proc/{me}/task/{me}/children").read_text().split())


def test_realtime_permitted_says_what_the_os_allows_and_changes_nothing() -> None:
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    assert realtime_permitted() is (os.geteuid() == 0)  # a test run as a user has no CAP_SYS_NICE
    assert (os.sched_getscheduler(0), os.sched_getparam(0)) == before
