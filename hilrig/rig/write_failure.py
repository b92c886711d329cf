"""A write the recording's disk refused (full, over quota, a file too large, failing): what the
recorder process tells the session (:class:`WriteFailure`, pickled over its pipe), and what the
session and ``hilrig record`` say of it."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from hilrig.outputs import DISK_ERRORS, disk_errno, nearest_existing


@dataclass(frozen=True)
class WriteFailure:
    """``errno`` (one of :data:`hilrig.outputs.DISK_ERRORS`) refused a write to the file system
    mounted at ``mount``; the file keeps its whole chunks, up to ``kept_until_ns`` (monotonic;
    0: none)."""

    errno: int
    mount: str
    kept_until_ns: int

    @property
    def problem(self) -> str:
        """What failed, e.g. ``the disk is full (/data)``: the session's ``ended_by``."""
        return f"{DISK_ERRORS[self.errno][0]} ({self.mount})"

    @property
    def remedy(self) -> str:
        """What to do, e.g. ``free space and run again``."""
        return DISK_ERRORS[self.errno][1]


def write_failure(err: BaseException, path: Path, kept_until_ns: int) -> WriteFailure | None:
    """``err`` as a :class:`WriteFailure` of the file at ``path`` if a disk refused the write
    behind it; None for any other error."""
    code = disk_errno(err)
    return None if code is None else WriteFailure(code, mount_point(path), kept_until_ns)


def mount_point(path: Path) -> str:
    """The mount point of the file system that holds ``path`` (or would: its nearest existing
    folder's)."""
    folder = nearest_existing(Path(os.path.abspath(path)))
    while not os.path.ismount(folder):
        folder = folder.parent
    return str(folder)
