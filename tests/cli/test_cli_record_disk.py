"""``hilrig record`` and its disk: refused before it starts on a disk that cannot hold it, warned
on one that may not, and, on a disk that fills while it records, ended in one line with a file
that keeps every sample of its whole chunks (``hilrig recover`` makes it whole).

Each test mounts a real tmpfs of its own (root only: skipped elsewhere), so writes fail as on a
full disk: ENOSPC, after some bytes may have gone in.
"""

from __future__ import annotations

import errno
import re
import shutil
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from hilrig.recording import load
from hilrig.rig.disk_space import BYTES_PER_S, FIXED_BYTES, expected_bytes
from hilrig.rig.machine_lock import WAITING

HILRIG = Path(sys.executable).with_name("hilrig")
Mount = Callable[[str], Path]


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Mount]:
    """``mount(size)``: a tmpfs of ``size`` (mount's ``size=``) at a fresh folder, unmounted at
    the test's end."""
    mounted: list[Path] = []

    def mount(size: str) -> Path:
        disk = tmp_path / f"disk-{uuid.uuid4().hex[:8]}"
        disk.mkdir()
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(disk)],
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here (needs root): {done.stderr.strip()}")
        mounted.append(disk)
        return disk

    yield mount
    for disk in mounted:
        subprocess.run(["umount", "--lazy", str(disk)], check=True)


def record(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [str(HILRIG), "record", "--subject", "S001", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def without_waiting(stderr: str) -> list[str]:
    """``stderr``'s lines but for its saying that it waits for another session (``make test``
    beside another)."""
    return [line for line in stderr.splitlines() if not line.startswith(f"waiting: {WAITING}")]


def fill(disk: Path) -> None:
    """Write zeros to ``disk`` until it is full."""
    with (disk / "filler").open("wb", buffering=0) as filler:
        block = bytes(1 << 20)
        try:
            while True:
                filler.write(block)
        except OSError as err:
            assert err.errno == errno.ENOSPC


def test_a_disk_that_fills_ends_the_session_in_one_line_keeping_every_whole_chunk(
    small_disk: Mount, tmp_path: Path
) -> None:
    disk = small_disk("64m")
    out = disk / "s.mcap"
    process = record("--duration", "20", "--out", str(out))
    try:
        assert process.stderr is not None
        line = process.stderr.readline()
        while line and "session started" not in line:  # waits for another session first
            line = process.stderr.readline()
        time.sleep(2.0)  # chunks are written every 0.25 s
        fill(disk)
        stdout, stderr = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 2, stderr
    assert "Traceback" not in stderr and "Exception ignored" not in stderr
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, stderr
    said = re.fullmatch(
        rf"error: the disk is full \({disk}\): the recording stopped at (\d+\.\d) s of 20 s;"
        rf" (\d+\.\d) s kept in {out}, cut at its last whole chunk \(`hilrig recover {out} -o"
        r" OUT` makes it whole\); free space and run again",
        errors[0],
    )
    assert said is not None, errors[0]
    stopped_s, kept_s = float(said[1]), float(said[2])
    assert 2.0 <= stopped_s < 20.0 and kept_s <= stopped_s
    ended = f"  ended early: the disk is full ({disk}) at {stopped_s:.1f} s; the robot was held"
    assert ended in stdout.splitlines()
    (disk / "filler").unlink()
    # cut at a chunk's end: unfinished (no summary), nothing damaged, nothing lost in recovery
    checked = subprocess.run([HILRIG, "info", "--check", out], capture_output=True, text=True)
    assert checked.returncode == 1 and "TRUNCATED" in checked.stdout
    assert "damaged" not in checked.stderr.lower()
    whole = tmp_path / "whole.mcap"
    recovered = subprocess.run(
        [HILRIG, "recover", out, "-o", whole], capture_output=True, text=True, check=False
    )
    assert recovered.returncode == 1, recovered.stderr
    assert "lost" not in recovered.stdout + recovered.stderr
    assert subprocess.run([HILRIG, "info", "--check", whole], capture_output=True).returncode == 0
    topics = load(whole, topics=["/diagnostics/loop", "/ft/wrist", "/events"])
    ticks = topics["/diagnostics/loop"]
    assert (ticks["tick"].to_numpy() == np.arange(1, len(ticks) + 1)).all()  # none missing
    assert (np.diff(topics["/ft/wrist"]["sequence"].to_numpy()) == 1).all()
    events = topics["/events"]
    start_ns = events[events["detail"] == "session started at the start pose"]["header.stamp_ns"]
    last_tick_s = (ticks["header.stamp_ns"].iloc[-1] - start_ns.iloc[0]) / 1e9
    assert abs(last_tick_s - kept_s) <= 0.1  # the line says how much of the session is kept


def test_a_disk_that_cannot_hold_the_session_is_refused_before_anything_starts(
    small_disk: Mount,
) -> None:
    disk = small_disk("2m")
    out = disk / "new" / "s.mcap"
    process = record("--duration", "20", "--out", str(out))
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 2
    assert without_waiting(stderr) == [
        f"error: {disk}: 2.1 MB free, not enough for this 20 s session of recording (about"
        f" {expected_bytes(20) / 1e6:.1f} MB at 640 kB/s): nothing was recorded; free space or"
        " record elsewhere (--out)"
    ]
    assert list(disk.iterdir()) == []  # not even the folder


def test_a_disk_with_little_room_for_the_session_is_warned_of(small_disk: Mount) -> None:
    needed = expected_bytes(3)
    disk = small_disk(f"{needed * 3 // 2 // 4096 * 4}k")  # 1.5 times: fits, under twice
    free = shutil.disk_usage(disk).free
    out = disk / "s.mcap"
    process = record("--duration", "3", "--out", str(out))
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 0, stderr
    warning = (
        f"warning: {disk}: {free / 1e6:.1f} MB free, less than twice this session's expected"
        f" {needed / 1e6:.1f} MB: about {(free - FIXED_BYTES) / BYTES_PER_S:.0f} s of recording"
        " fit"
    )
    assert warning in stderr.splitlines()
    assert subprocess.run([HILRIG, "info", "--check", out], capture_output=True).returncode == 0
