"""The F/T sensor's serial port (``hilrig doctor --port``): a real pty, a missing path, a file,
access refused to a real other user, and a USB adapter's latency timer in a copy of /sys."""

from __future__ import annotations

import grp
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from hilrig.machine import Setting, port_settings


@pytest.fixture
def pty_path() -> Iterator[Path]:
    parent, child = os.openpty()
    try:
        yield Path(os.ttyname(child))
    finally:
        os.close(parent)
        os.close(child)


def test_a_pty_is_a_port_without_a_device(pty_path: Path) -> None:
    assert port_settings(pty_path) == [
        Setting("F/T port", str(pty_path), "ok", "a character device"),
        Setting("F/T port access", "read and write", "ok", ""),
        Setting("F/T port driver", "none", "note", "not a device of /sys (a pty)"),
    ]


def test_a_missing_port_and_a_file_are_one_warning_each(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("")
    assert port_settings(tmp_path / "ttyUSB9") == [
        Setting(
            "F/T port",
            str(tmp_path / "ttyUSB9"),
            "warn",
            "No such file or directory: is the sensor plugged in?",
        )
    ]
    assert port_settings(tmp_path / "file") == [
        Setting(
            "F/T port",
            str(tmp_path / "file"),
            "warn",
            "not a character device: not a serial port",
        )
    ]


def test_a_link_to_the_port_is_shown_with_where_it_leads(tmp_path: Path, pty_path: Path) -> None:
    link = tmp_path / "by-id-sensor"
    link.symlink_to(pty_path)
    assert port_settings(link)[0].value == f"{link} -> {pty_path}"


def test_another_user_is_told_which_group_to_join(
    pty_path: Path, as_nobody: Callable[[Callable[[], object]], str]
) -> None:
    group = grp.getgrgid(os.stat(pty_path).st_gid).gr_name
    seen = as_nobody(lambda: port_settings(pty_path)[1])
    expected = Setting(
        "F/T port access",
        "refused",
        "warn",
        f"this user may not read and write it: add the user to the port's group ({group})",
    )
    assert seen == repr(expected)


def usb_adapter(tmp_path: Path, latency_timer_ms: int) -> tuple[Path, Path]:
    """A character device named ttyUSB0 and a copy of /sys where it is an FTDI adapter."""
    port = tmp_path / "dev" / "ttyUSB0"
    port.parent.mkdir()
    try:
        os.mknod(port, 0o600 | stat.S_IFCHR, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("making a device node needs root")
    sys_root = tmp_path / "machine"
    usb = sys_root / "sys/devices/pci0000:00/usb1/1-1/1-1:1.0/ttyUSB0"
    usb.mkdir(parents=True)
    (usb / "latency_timer").write_text(f"{latency_timer_ms}\n")
    driver = sys_root / "sys/bus/usb-serial/drivers/ftdi_sio"
    driver.mkdir(parents=True)
    (usb / "driver").symlink_to(driver)
    tty = sys_root / "sys/class/tty/ttyUSB0"
    tty.mkdir(parents=True)
    (tty / "device").symlink_to(usb)
    return port, sys_root


def test_an_ftdi_adapter_s_16_ms_latency_timer_is_a_warning(tmp_path: Path) -> None:
    port, sys_root = usb_adapter(tmp_path, 16)
    settings = port_settings(port, sys_root)
    assert settings[2] == Setting("F/T port driver", "ftdi_sio", "note", "")
    assert settings[3] == Setting(
        "F/T port latency timer",
        "16 ms",
        "warn",
        "the adapter holds received bytes up to 16 ms, 16 periods at 1 kHz: echo 1 > "
        "/sys/bus/usb-serial/devices/ttyUSB0/latency_timer (as root; a udev rule keeps it)",
    )


def test_a_1_ms_latency_timer_is_ok(tmp_path: Path) -> None:
    port, sys_root = usb_adapter(tmp_path, 1)
    assert port_settings(port, sys_root)[3].verdict == "ok"
