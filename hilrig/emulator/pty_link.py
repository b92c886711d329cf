"""The emulated sensor's serial port: a raw pty pair behind a symlink made only where nothing is.

The link is never made over an existing file, device node or link, and removed only while it is
still this pty's, so ``--port-path`` can never destroy anything.
"""

from __future__ import annotations

import os
import tty
from pathlib import Path

from hilrig.errors import HilrigError


class PtyLink:
    """One raw pty pair; the slave stays open here so the master never reads EIO."""

    def __init__(self, link: Path) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.target = os.ttyname(self.slave)
        try:  # only where nothing is: never over a file, a device node or someone's link
            os.symlink(self.target, link)
        except OSError as error:
            os.close(self.master)
            os.close(self.slave)
            why = "already exists" if isinstance(error, FileExistsError) else error.strerror
            raise HilrigError(
                f"{link}: {why}; the emulated sensor's port is created only where nothing is"
            ) from None

    def write(self, data: bytes | bytearray) -> int:
        try:
            return os.write(self.master, data)
        except BlockingIOError:
            return 0

    def close(self, link: Path) -> None:
        """Close the pair; remove ``link`` only while it is still this pty's symlink."""
        if link.is_symlink() and os.readlink(link) == self.target:
            link.unlink()
        os.close(self.master)
        os.close(self.slave)
