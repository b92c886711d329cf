"""Will a session's recording fit on its disk? Checked before a session starts, against the
size a session is expected to write: a warning below :data:`MARGIN` times that, a refusal (one
line, nothing made) when the disk cannot hold :data:`AT_LEAST_S` of it (or all of a shorter
session). The estimate is made here alone."""

from __future__ import annotations

import shutil
from pathlib import Path

from hilrig.errors import DiskError
from hilrig.outputs import nearest_existing

#: Bytes a session writes per second: 1 kHz F/T, joint-state (500 Hz), tick and servo-call (200
#: Hz) rows and their events, zstd-compressed; measured on the emulated rig (4 s and 12 s
#: sessions: 2.52 and 7.40 MB, 610 kB/s), rounded up. A slower loop writes less.
BYTES_PER_S = 640_000
#: Bytes a session writes whatever its length: metadata, attachments (the URDF), start-up rows.
FIXED_BYTES = 256_000
#: A disk with less free space than this many times a session's expected size is warned of.
MARGIN = 2.0
#: A disk that cannot hold this much of a session (or all of a shorter one) is refused.
AT_LEAST_S = 60.0


def expected_bytes(duration_s: float) -> int:
    """The bytes a recording of ``duration_s`` seconds is expected to take."""
    return round(FIXED_BYTES + BYTES_PER_S * duration_s)


def check_free_space(path: Path, duration_s: float | None) -> str:
    """A warning (one line; "" for none) if the disk of the recording ``path`` (or of its
    nearest existing folder) has less than :data:`MARGIN` times the expected size of a
    ``duration_s`` session (None: until stopped, a minute's); raises DiskError if it cannot
    hold :data:`AT_LEAST_S` (or all of a shorter session)."""
    folder = nearest_existing(path.parent)
    free = shutil.disk_usage(folder).free
    needed_s = AT_LEAST_S if duration_s is None else min(duration_s, AT_LEAST_S)
    if free < expected_bytes(needed_s):
        what = "a minute" if needed_s == AT_LEAST_S else f"this {needed_s:g} s session"
        raise DiskError(
            f"{folder}: {_mb(free)} free, not enough for {what} of recording (about"
            f" {_mb(expected_bytes(needed_s))} at {BYTES_PER_S / 1000:g} kB/s): nothing was"
            " recorded; free space or record elsewhere (--out)"
        )
    session_s = AT_LEAST_S if duration_s is None else duration_s
    if free >= MARGIN * expected_bytes(session_s):
        return ""
    fits_s = (free - FIXED_BYTES) / BYTES_PER_S
    return (
        f"{folder}: {_mb(free)} free, less than twice this session's expected"
        f" {_mb(expected_bytes(session_s))}: about {fits_s:.0f} s of recording fit"
    )


def _mb(size: int) -> str:
    return f"{size / 1e6:.1f} MB"
