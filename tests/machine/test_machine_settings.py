"""The machine's settings (``hilrig doctor``): each fact read from a copy of /proc and /sys as
another machine would have them, and from this machine against the kernel's own answers."""

from __future__ import annotations

import gzip
import os
import re
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from hilrig.machine import Setting, read_settings
from hilrig.machine.settings import SYSTEM
from hilrig.timing import CPU_LATENCY_DEVICE

NAMES = [
    "CPUs",
    "real-time scheduling",
    "idle states",
    "kernel preemption",
    "isolated CPUs",
    "real-time throttling",
    "kernel's unbound workers",
    "clock source",
    "CPU frequency",
    "virtual machine",
]


def machine(root: Path, files: dict[str, str | bytes]) -> Path:
    """A copy of a machine's /proc and /sys under ``root`` with ``files`` in it."""
    for path, content in files.items():
        target = root / path
        target.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            target.write_bytes(content)
        else:
            target.write_text(content + "\n")
    return root


def setting(root: Path, name: str) -> Setting:
    found = [s for s in read_settings(root) if s.name == name]
    assert len(found) == 1
    return found[0]


def stat_line(pid: int, comm: str, policy: int, priority: int = 0, parent: int = 2) -> str:
    """A /proc/PID/stat line: fields 3.. after ``(comm)``; field 4 the parent's pid (2 for a
    kernel thread), 40 rt_priority, 41 policy."""
    fields = ["S", str(parent)] + ["0"] * 35 + [str(priority), str(policy)] + ["0"] * 11
    return f"{pid} ({comm}) " + " ".join(fields)


def test_an_empty_machine_reads_as_unknown_in_the_documented_order(tmp_path: Path) -> None:
    settings = read_settings(tmp_path)
    assert [s.name for s in settings] == NAMES
    assert [(s.value, s.verdict) for s in settings] == [
        ("unknown", "note"),
        ("not tried", "note"),
        ("none", "note"),
        ("unknown", "note"),
        ("none", "note"),
        ("unknown", "note"),
        ("none seen", "note"),
        ("unknown", "note"),
        ("not exposed", "note"),
        ("no", "ok"),
    ]


@pytest.mark.parametrize(
    ("online", "value", "verdict", "note"),
    [
        ("0-3,6", "0-3,6", "ok", "5 online"),
        ("0-1", "0-1", "ok", "2 online"),
        ("0", "0", "warn", "one CPU: the loop, the rig and the recorder share it"),
    ],
)
def test_cpus(tmp_path: Path, online: str, value: str, verdict: str, note: str) -> None:
    root = machine(tmp_path, {"sys/devices/system/cpu/online": online})
    assert setting(root, "CPUs") == Setting("CPUs", value, verdict, note)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("files", "value", "verdict"),
    [
        (
            {"sys/kernel/debug/sched/preempt": "none (voluntary) full lazy"},
            "voluntary (debugfs)",
            "warn",
        ),
        ({"sys/kernel/debug/sched/preempt": "none voluntary (full) lazy"}, "full (debugfs)", "ok"),
        ({"sys/kernel/realtime": "1"}, "rt (/sys/kernel/realtime)", "ok"),
        ({"proc/cmdline": "quiet preempt=full ro"}, "full (boot parameter)", "ok"),
        ({"proc/cmdline": "preempt=none"}, "none (boot parameter)", "warn"),
        (
            {"proc/config.gz": gzip.compress(b"CONFIG_PREEMPT_BUILD=y\nCONFIG_PREEMPT_NONE=y\n")},
            "none (the kernel's build default)",
            "warn",
        ),
        (
            {"proc/config.gz": gzip.compress(b"CONFIG_PREEMPT=y\nCONFIG_PREEMPT_RT=y\n")},
            "rt (the kernel's build default)",
            "ok",
        ),
        ({"proc/config.gz": b"not gzip"}, "unknown", "note"),
    ],
)
def test_preemption_model(
    tmp_path: Path, files: dict[str, str | bytes], value: str, verdict: str
) -> None:
    found = setting(machine(tmp_path, files), "kernel preemption")
    assert (found.value, found.verdict) == (value, verdict)


def test_a_kernel_that_does_not_preempt_says_what_to_change(tmp_path: Path) -> None:
    found = setting(machine(tmp_path, {"proc/cmdline": "preempt=voluntary"}), "kernel preemption")
    assert found.note.endswith("boot with preempt=full, or a PREEMPT_RT kernel")


@pytest.mark.parametrize(
    ("isolated", "verdict", "note_end"),
    [
        ("2-3", "ok", "hilrig record --cpu 2"),
        ("", "note", "hilrig record --cpu N keep one for it)"),
    ],
)
def test_isolated_cpus(tmp_path: Path, isolated: str, verdict: str, note_end: str) -> None:
    found = setting(
        machine(tmp_path, {"sys/devices/system/cpu/isolated": isolated}), "isolated CPUs"
    )
    assert (found.value, found.verdict) == (isolated or "none", verdict)
    assert found.note.endswith(note_end)


@pytest.mark.parametrize(
    ("runtime", "value", "verdict"),
    [
        ("950000", "95 %", "ok"),
        ("400000", "40 %", "warn"),
        ("-1", "off", "note"),
        ("lots", "unknown", "note"),
    ],
)
def test_realtime_throttling(tmp_path: Path, runtime: str, value: str, verdict: str) -> None:
    root = machine(
        tmp_path,
        {
            "proc/sys/kernel/sched_rt_runtime_us": runtime,
            "proc/sys/kernel/sched_rt_period_us": "1000000",
        },
    )
    found = setting(root, "real-time throttling")
    assert (found.value, found.verdict) == (value, verdict)


@pytest.mark.parametrize(
    ("policies", "value", "verdict"),
    [((0, 0), "2 at normal priority", "warn"), ((1, 0), "1 of 2 real-time", "ok")],
)
def test_kernel_workers_by_their_policy(
    tmp_path: Path, policies: tuple[int, int], value: str, verdict: str
) -> None:
    files = {
        f"proc/{100 + i}/stat": stat_line(100 + i, f"kworker/u8:{i}", policy, policy)
        for i, policy in enumerate(policies)
    }
    files["proc/7/stat"] = stat_line(7, "kworker/0:1H", 1, 1)  # a bound worker: not counted
    files["proc/8/stat"] = stat_line(8, "kworker/u9:9", 1, 1, parent=1)  # a user's process
    files["proc/9/stat"] = "9 (kworker/u1:1) S 2 0"  # cut short: not counted
    found = setting(machine(tmp_path, files), "kernel's unbound workers")
    assert (found.value, found.verdict) == (value, verdict)


@pytest.mark.parametrize(
    ("path", "content", "name", "verdict"),
    [
        (
            "sys/devices/system/clocksource/clocksource0/current_clocksource",
            "tsc",
            "clock source",
            "ok",
        ),
        (
            "sys/devices/system/clocksource/clocksource0/current_clocksource",
            "hpet",
            "clock source",
            "warn",
        ),
        (
            "sys/devices/system/cpu/cpu0/cpufreq/scaling_governor",
            "performance",
            "CPU frequency",
            "ok",
        ),
        (
            "sys/devices/system/cpu/cpu0/cpufreq/scaling_governor",
            "powersave",
            "CPU frequency",
            "warn",
        ),
        ("proc/cpuinfo", "flags\t\t: fpu vme hypervisor lahf_lm", "virtual machine", "note"),
        ("proc/cpuinfo", "flags\t\t: fpu vme lahf_lm", "virtual machine", "ok"),
        ("sys/devices/system/cpu/cpuidle/current_driver", "intel_idle", "idle states", "note"),
    ],
)
def test_one_fact_each(tmp_path: Path, path: str, content: str, name: str, verdict: str) -> None:
    found = setting(machine(tmp_path, {path: content}), name)
    assert found.verdict == verdict
    assert found.value in (content, "yes", "no")


def test_this_machine_answers_as_its_kernel_does() -> None:
    settings = {s.name: s for s in read_settings(SYSTEM)}
    assert list(settings) == NAMES
    tried: list[bool] = []

    def try_fifo() -> None:  # the oracle: the kernel's own answer, on a thread of its own
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except PermissionError:
            tried.append(False)
        else:
            tried.append(True)

    thread = threading.Thread(target=try_fifo)
    thread.start()
    thread.join()
    assert settings["real-time scheduling"].value == ("granted" if tried[0] else "refused")
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the check left this thread as it was
    # the kernel starts and ends workers meanwhile: their count may differ, not their kind
    raised = any(policy != os.SCHED_OTHER for policy in unbound_worker_policies())
    workers = settings["kernel's unbound workers"]
    pattern = r"\d+ of \d+ real-time" if raised else r"\d+ at normal priority"
    assert re.fullmatch(pattern, workers.value), workers
    assert workers.verdict == ("ok" if raised else "warn")


def test_another_user_may_not_hold_idle_cpus_awake(
    as_nobody: Callable[[Callable[[], object]], str],
) -> None:
    """Checked for real: /dev/cpu_dma_latency is root's alone; a child as user nobody reads
    the settings (the module is loaded already) and says so."""
    if not Path(CPU_LATENCY_DEVICE).exists():
        pytest.skip("no PM QoS device here")
    seen = as_nobody(lambda: setting(SYSTEM, "idle states"))
    driver = Path("/sys/devices/system/cpu/cpuidle/current_driver")
    name = driver.read_text().strip() if driver.exists() else "none"
    if name == "none":
        note = "an idle CPU halts and is slow to wake; the loop's idle spinners need root"
        expected = Setting("idle states", "no idle driver", "warn", note)
    else:
        note = (
            "idle CPUs may enter deep states, slow to wake: the loop's PM QoS request needs root "
            f"({CPU_LATENCY_DEVICE})"
        )
        expected = Setting("idle states", name, "warn", note)
    assert seen == repr(expected)


def unbound_worker_policies() -> list[int]:
    """The scheduling policy of each of the kernel's unbound workers, found by name and asked of
    the kernel (the oracle's own reading, not the stat files')."""
    policies = []
    for entry in os.listdir("/proc"):
        try:
            if entry.isdigit() and Path(f"/proc/{entry}/comm").read_text().startswith("kworker/u"):
                policies.append(os.sched_getscheduler(int(entry)))
        except OSError:  # ended meanwhile
            continue
    return policies
