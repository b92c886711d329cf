"""What a Linux machine's settings say about running the 1 kHz loop on it (/proc and /sys).

Each :class:`Setting` is one fact, a verdict and a one-line note: ``ok``, ``warn`` (it costs
deadlines; the note says what to change) or ``note`` (worth knowing, nothing to change). The
files are read under ``root`` (``/`` for this machine; a copy of another machine's /proc and /sys
reads as that machine, but for what is tried rather than read: real-time scheduling, and whether
idle CPUs may be held awake). Why each matters, measured: docs/rig-timing.md.
"""

from __future__ import annotations

import contextlib
import gzip
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from hilrig.timing import CPU_LATENCY_DEVICE, REALTIME_PRIORITY, realtime_permitted

Verdict = Literal["ok", "warn", "note"]
SYSTEM = Path("/")
#: The settings whose warning a recorded session repeats as it starts (``hilrig record``): a
#: loop at normal priority, CPUs let into slow idle states, a sensor port that holds bytes or
#: may not be read.
SESSION_WARNINGS = (
    "real-time scheduling",
    "idle states",
    "F/T port access",
    "F/T port latency timer",
)
SCHED_FIFO, SCHED_RR = "1", "2"  # the policy numbers in /proc/PID/stat
KTHREADD_PID = "2"  # the parent of every kernel thread
CLOCKS_OK = ("tsc", "arch_sys_counter", "kvm-clock", "hyperv_clocksource_tsc_page")
PREEMPT_CONFIG = {  # the kernel's build-time default model, by its config option
    "CONFIG_PREEMPT_RT": "rt",
    "CONFIG_PREEMPT_LAZY": "lazy",
    "CONFIG_PREEMPT": "full",
    "CONFIG_PREEMPT_VOLUNTARY": "voluntary",
    "CONFIG_PREEMPT_NONE": "none",
}


@dataclass(frozen=True)
class Setting:
    """One fact about the machine, its verdict for the loop and what it means."""

    name: str
    value: str
    verdict: Verdict
    note: str


def session_warnings(settings: Iterable[Setting]) -> list[str]:
    """One line for each of ``settings`` that warns and is one of :data:`SESSION_WARNINGS`."""
    return [
        f"{s.name}: {s.value} - {s.note} (hilrig doctor)"
        for s in settings
        if s.verdict == "warn" and s.name in SESSION_WARNINGS
    ]


def read_settings(root: Path = SYSTEM) -> list[Setting]:
    """The machine's settings that bear on the loop, in the order the docs explain them."""
    return [
        _cpus(root),
        _realtime(root),
        _idle(root),
        _preemption(root),
        _isolated(root),
        _throttling(root),
        _kernel_workers(root),
        _clock(root),
        _governor(root),
        _hypervisor(root),
    ]


def _read(root: Path, path: str) -> str | None:
    """The stripped text of ``root/path``; None where it is absent or may not be read."""
    try:
        return (root / path.lstrip("/")).read_text().strip()
    except OSError:
        return None


def _cpus(root: Path) -> Setting:
    online = _read(root, "sys/devices/system/cpu/online")
    count = 0 if online is None else _count_cpus(online)
    if online is None or count == 0:
        return Setting("CPUs", "unknown", "note", "not readable here")
    if count == 1:
        return Setting(
            "CPUs", online, "warn", "one CPU: the loop, the rig and the recorder share it"
        )
    return Setting("CPUs", online, "ok", f"{count} online")


def _count_cpus(cpu_list: str) -> int:
    """How many CPUs a kernel CPU list (``0-3,6``) names; 0 if it names none or is unreadable."""
    count = 0
    for part in cpu_list.split(","):
        low, _, high = part.partition("-")
        with contextlib.suppress(ValueError):
            count += int(high or low) - int(low) + 1
    return count


def _realtime(root: Path) -> Setting:
    name = "real-time scheduling"
    if root != SYSTEM:
        return Setting(name, "not tried", "note", "tried only on the machine running the check")
    if realtime_permitted():
        return Setting(
            name,
            "granted",
            "ok",
            f"the loop's thread runs under SCHED_FIFO {REALTIME_PRIORITY}",
        )
    return Setting(
        name,
        "refused",
        "warn",
        "the loop runs at normal priority, behind any busy process: it needs CAP_SYS_NICE "
        "(root has it) or an rtprio limit (limits.conf)",
    )


def _idle(root: Path) -> Setting:
    name = "idle states"
    driver = _read(root, "sys/devices/system/cpu/cpuidle/current_driver") or "none"
    if root != SYSTEM:
        return Setting(
            name, driver, "note", "whether idle CPUs may be held awake is tried only here"
        )
    request = _may_write(CPU_LATENCY_DEVICE)
    if driver == "none":
        if request:
            return Setting(
                name,
                "no idle driver",
                "ok",
                "an idle CPU halts; while the loop runs, one idle spinner per CPU keeps it awake",
            )
        return Setting(
            name,
            "no idle driver",
            "warn",
            "an idle CPU halts and is slow to wake; the loop's idle spinners need root",
        )
    if request:
        return Setting(
            name, driver, "ok", "while the loop runs, idle CPUs poll (a PM QoS request of 0 us)"
        )
    return Setting(
        name,
        driver,
        "warn",
        f"idle CPUs may enter deep states, slow to wake: the loop's PM QoS request needs root "
        f"({CPU_LATENCY_DEVICE})",
    )


def _may_write(path: str) -> bool:
    try:
        os.close(os.open(path, os.O_WRONLY))
    except OSError:
        return False
    return True


def _preemption(root: Path) -> Setting:
    name = "kernel preemption"
    model, source = _preempt_model(root)
    if model in ("rt", "full", "lazy"):
        return Setting(name, f"{model} ({source})", "ok", "the loop preempts kernel code at once")
    if model in ("none", "voluntary"):
        return Setting(
            name,
            f"{model} ({source})",
            "warn",
            "a thread in kernel code keeps its CPU until it yields, and the loop waits: boot "
            "with preempt=full, or a PREEMPT_RT kernel",
        )
    return Setting(name, "unknown", "note", "not readable here")


def _preempt_model(root: Path) -> tuple[str, str]:
    """The kernel's preemption model and where it was read; ("", "") if nowhere."""
    debug = _read(root, "sys/kernel/debug/sched/preempt")  # e.g. "none (voluntary) full lazy"
    if debug and (chosen := re.search(r"\((\w+)\)", debug)):
        return chosen.group(1), "debugfs"
    if _read(root, "sys/kernel/realtime") == "1":
        return "rt", "/sys/kernel/realtime"
    cmdline = _read(root, "proc/cmdline") or ""
    if given := re.search(r"(?:^|\s)preempt=(\w+)", cmdline):
        return given.group(1), "boot parameter"
    try:
        config = gzip.decompress((root / "proc/config.gz").read_bytes()).decode()
    except (OSError, EOFError, gzip.BadGzipFile):
        return "", ""
    options = set(re.findall(r"^(CONFIG_PREEMPT\w*)=y$", config, re.MULTILINE))
    for option, model in PREEMPT_CONFIG.items():
        if option in options:
            return model, "the kernel's build default"
    return "", ""


def _isolated(root: Path) -> Setting:
    name = "isolated CPUs"
    isolated = _read(root, "sys/devices/system/cpu/isolated")
    if isolated:
        first = isolated.split(",")[0].split("-")[0]
        return Setting(name, isolated, "ok", f"kept free: hilrig record --cpu {first}")
    return Setting(
        name,
        "none",
        "note",
        "the loop shares its CPUs with every process (isolcpus=N at boot and hilrig record "
        "--cpu N keep one for it)",
    )


def _throttling(root: Path) -> Setting:
    name = "real-time throttling"
    runtime = _read(root, "proc/sys/kernel/sched_rt_runtime_us")
    period = _read(root, "proc/sys/kernel/sched_rt_period_us")
    if runtime is None or period is None:
        return Setting(name, "unknown", "note", "not readable here")
    if runtime == "-1":
        return Setting(name, "off", "note", "a runaway real-time thread could hold a CPU for good")
    try:
        share = 100 * int(runtime) / int(period)
    except (ValueError, ZeroDivisionError):
        return Setting(name, "unknown", "note", f"unreadable: {runtime} of {period} us")
    verdict: Verdict = "ok" if share >= 50 else "warn"
    return Setting(
        name, f"{share:g} %", verdict, f"real-time threads may take {share:g} % of a CPU"
    )


def _kernel_workers(root: Path) -> Setting:
    name = "kernel's unbound workers"
    raised = total = 0
    for stat in (root / "proc").glob("[0-9]*/stat"):
        text = _read(root, str(stat.relative_to(root)))
        if text is None or "(kworker/u" not in text:
            continue
        fields = text.rsplit(")", 1)[1].split()  # fields[0] is the stat file's field 3
        if len(fields) < 39 or fields[1] != KTHREADD_PID:  # not the kernel's (a name is free)
            continue
        total += 1
        raised += fields[38] in (SCHED_FIFO, SCHED_RR)
    if total == 0:
        return Setting(name, "none seen", "note", "not readable here")
    if raised:
        return Setting(name, f"{raised} of {total} real-time", "ok", "as an operator's tuning")
    return Setting(
        name,
        f"{total} at normal priority",
        "warn",
        "a serial port's bytes are handed on by one of them and can wait behind busy processes "
        "(docs/rig-timing.md: giving the tty's worker priority)",
    )


def _clock(root: Path) -> Setting:
    name = "clock source"
    clock = _read(root, "sys/devices/system/clocksource/clocksource0/current_clocksource")
    if clock is None:
        return Setting(name, "unknown", "note", "not readable here")
    if clock in CLOCKS_OK:
        return Setting(name, clock, "ok", "read in user space, in well under a microsecond")
    return Setting(
        name,
        clock,
        "warn",
        "each clock read enters the kernel, and the loop reads the clock several times a tick",
    )


def _governor(root: Path) -> Setting:
    name = "CPU frequency"
    governor = _read(root, "sys/devices/system/cpu/cpu0/cpufreq/scaling_governor")
    if governor is None:
        return Setting(name, "not exposed", "note", "set by the firmware or the host")
    if governor == "performance":
        return Setting(name, governor, "ok", "CPUs at full speed")
    return Setting(
        name,
        governor,
        "warn",
        "a CPU slowed while idle takes time to speed up: the 'performance' governor for sessions",
    )


def _hypervisor(root: Path) -> Setting:
    name = "virtual machine"
    cpuinfo = _read(root, "proc/cpuinfo") or ""
    if re.search(r"^flags\s*:.*\bhypervisor\b", cpuinfo, re.MULTILINE):
        return Setting(
            name,
            "yes",
            "note",
            "the host can stop a vCPU for milliseconds (steal); no setting in it wins that back",
        )
    return Setting(name, "no", "ok", "")
