"""The emulated sensor's port link: made only where nothing is, removed only while it is ours."""

import os
from pathlib import Path

import pytest

from hilrig.emulator import FtEmulator
from hilrig.errors import HilrigError


def test_an_existing_file_is_refused_and_kept(tmp_path: Path) -> None:
    existing = tmp_path / "ttyUSB0"
    existing.write_text("not a pty")
    with pytest.raises(HilrigError) as caught:
        FtEmulator(port_path=existing).start()
    assert str(caught.value) == (
        f"{existing}: already exists; the emulated sensor's port is created only where nothing is"
    )
    assert existing.read_text() == "not a pty"


def test_a_missing_folder_is_one_line(tmp_path: Path) -> None:
    port = tmp_path / "no-such-folder" / "ft"
    with pytest.raises(HilrigError) as caught:
        FtEmulator(port_path=port).start()
    assert str(caught.value) == (
        f"{port}: No such file or directory; the emulated sensor's port is created only where "
        "nothing is"
    )


def test_the_link_is_removed_at_close_only_while_it_is_the_emulators(tmp_path: Path) -> None:
    port = tmp_path / "ft"
    with FtEmulator(port_path=port):
        assert port.is_symlink() and os.readlink(port).startswith("/dev/pts/")
    assert not port.exists() and not port.is_symlink()
    with FtEmulator(port_path=port):
        port.unlink()
        port.write_text("put here by someone else while the emulator ran")
    assert port.read_text() == "put here by someone else while the emulator ran"
