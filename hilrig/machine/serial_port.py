"""What a serial port's settings say about a 1 kHz sensor on it (the wrist F/T sensor's port).

The port must be a character device this user may read and write; a USB-serial adapter of the
FTDI kind holds received bytes up to its *latency timer* (16 ms by default) before passing them
on, so a 1 kHz frame can wait 16 periods (the usual fix, as for Dynamixel servos and most
serial F/T sensors: 1 ms). Read from the device node and /sys, without opening the port (opening
it may toggle its modem lines). Same :class:`~hilrig.machine.settings.Setting` rows as the
machine's; ``root`` as there.
"""

from __future__ import annotations

import grp
import os
import stat
from pathlib import Path

from hilrig.machine.settings import SYSTEM, Setting

LATENCY_OK_MS = 1


def port_settings(port: Path, root: Path = SYSTEM) -> list[Setting]:
    """The port's settings: the device, this user's access, its driver and its latency timer
    (where the driver has one)."""
    try:
        mode = os.stat(port).st_mode
    except OSError as err:
        why = err.strerror or type(err).__name__
        return [Setting("F/T port", str(port), "warn", f"{why}: is the sensor plugged in?")]
    if not stat.S_ISCHR(mode):
        return [Setting("F/T port", str(port), "warn", "not a character device: not a serial port")]
    real = Path(os.path.realpath(port))
    shown = str(port) if real == port else f"{port} -> {real}"
    settings = [Setting("F/T port", shown, "ok", "a character device"), _access(port)]
    device = root / "sys/class/tty" / real.name / "device"
    driver = _driver(device)
    if driver is None:
        settings.append(Setting("F/T port driver", "none", "note", "not a device of /sys (a pty)"))
        return settings
    settings.append(Setting("F/T port driver", driver, "note", ""))
    timer = _latency_timer(device)
    if timer is not None:
        settings.append(_latency(real.name, timer))
    return settings


def _access(port: Path) -> Setting:
    name = "F/T port access"
    if os.access(port, os.R_OK | os.W_OK):
        return Setting(name, "read and write", "ok", "")
    try:
        group = grp.getgrgid(os.stat(port).st_gid).gr_name
    except KeyError:
        group = str(os.stat(port).st_gid)
    return Setting(
        name,
        "refused",
        "warn",
        f"this user may not read and write it: add the user to the port's group ({group})",
    )


def _driver(device: Path) -> str | None:
    """The kernel driver's name of the tty's device; None if it has no device in /sys."""
    try:
        return Path(os.readlink(device / "driver")).name
    except OSError:
        return None


def _latency_timer(device: Path) -> int | None:
    try:
        return int((device / "latency_timer").read_text().strip())
    except (OSError, ValueError):
        return None


def _latency(tty: str, timer_ms: int) -> Setting:
    name = "F/T port latency timer"
    if timer_ms <= LATENCY_OK_MS:
        return Setting(name, f"{timer_ms} ms", "ok", "received bytes are passed on within 1 ms")
    return Setting(
        name,
        f"{timer_ms} ms",
        "warn",
        f"the adapter holds received bytes up to {timer_ms} ms, {timer_ms} periods at 1 kHz: "
        f"echo 1 > /sys/bus/usb-serial/devices/{tty}/latency_timer (as root; a udev rule keeps it)",
    )
