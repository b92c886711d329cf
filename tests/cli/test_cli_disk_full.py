"""Every command that writes files, on a disk that is full: one line that says so, exit status 2,
no traceback, and nothing left on the disk (no partial output, no hidden temporary).

The disk is a real tmpfs of 1 MiB mounted for each test and filled to its last page, so each
write fails as it does on a full disk: with ENOSPC, after some bytes may have gone in.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
sys.path.insert(0, str(Path(__file__).parents[1] / "study"))
from analysis_helpers import write_session
from study_helpers import write_study

HILRIG = Path(sys.executable).with_name("hilrig")
FREE_BYTES = 4096  # one page left: every output here is larger
FULL = "the disk is full"
REMEDY = "nothing was written; free space and run again"


@dataclass(frozen=True)
class Inputs:
    session: Path  # 6 s of the paper's collisions
    study: Path  # 3 subjects x 2 controllers


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    root = tmp_path_factory.mktemp("inputs")
    session = write_session(
        root / "s.mcap", subject_id="S001", session_id="20260101-000001-S001", duration_s=6.0
    )
    write_study(root / "study", ["S01", "S02", "S03"], ["adaptive", "fixed"], duration_s=6.0)
    return Inputs(session, root / "study")


@pytest.fixture
def full_disk(tmp_path: Path) -> Iterator[Path]:
    """A 1 MiB tmpfs of its own, mounted at a fresh folder and filled but for FREE_BYTES."""
    disk = tmp_path / f"disk-{uuid.uuid4().hex[:8]}"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)],
        capture_output=True,
        text=True,
        check=False,
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {mounted.stderr.strip()}")
    try:
        stats = os.statvfs(disk)
        (disk / "filler").write_bytes(bytes(stats.f_bavail * stats.f_frsize - FREE_BYTES))
        stats = os.statvfs(disk)
        assert stats.f_bavail * stats.f_frsize == FREE_BYTES
        yield disk
    finally:
        subprocess.run(["umount", "--lazy", str(disk)], check=True)


def _paths(disk: Path) -> set[str]:
    """Everything on ``disk`` (hidden files too), relative to it."""
    return {str(p.relative_to(disk)) for p in disk.rglob("*")}


Command = Callable[[Inputs, Path], list[str]]
#: Each writing command with its output on the disk ``d``, and what the line says it could
#: not write: (arguments, file named, its folder relative to the disk).
COMMANDS: dict[str, tuple[Command, str, str]] = {
    "recover": (lambda i, d: ["recover", str(i.session), "-o", str(d / "r.mcap")], "r.mcap", ""),
    "export parquet": (
        lambda i, d: ["export", str(i.session), "--out", str(d / "tables")],
        r"\d+ files",
        "tables",
    ),
    "export csv": (
        lambda i, d: ["export", str(i.session), "--format", "csv", "--out", str(d / "t")],
        r"\d+ files",
        "t",
    ),
    "replay parquet": (
        lambda i, d: ["replay", str(i.session), "-c", "fixed", "-o", str(d / "r.parquet")],
        "r.parquet",
        "",
    ),
    "replay mcap": (
        lambda i, d: ["replay", str(i.session), "-c", "fixed", "-o", str(d / "r.mcap")],
        "r.mcap",
        "",
    ),
    "analyze table": (
        lambda i, d: ["analyze", str(i.session), "--out", str(d / "a.csv")],
        "a.csv",
        "",
    ),
    "analyze dataset": (
        lambda i, d: ["analyze", str(i.session), "--out", str(d / "dataset")],
        "part-0.parquet",
        "dataset/subject_id=S001/controller=adaptive/session_id=20260101-000001-S001",
    ),
    "report": (
        lambda i, d: ["report", str(i.study), "-o", str(d / "r.html"), "--resamples", "200"],
        "r.html",
        "",
    ),
    "view --save": (
        lambda i, d: ["view", str(i.session), "-c", "fixed", "--save", str(d / "v.rrd")],
        "v.rrd",
        "",
    ),
    "paper": (lambda i, d: ["paper", "--out", str(d / "paper")], r"\d+ files", "paper"),
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_full_disk_is_one_line_and_leaves_nothing(
    name: str, inputs: Inputs, full_disk: Path
) -> None:
    command, what, folder = COMMANDS[name]
    before = _paths(full_disk)
    done = _hilrig(*command(inputs, full_disk))
    assert done.returncode == 2, done.stderr
    where = re.escape(str(full_disk / folder) if folder else str(full_disk))
    expected = rf"error: {FULL}: could not write {what} \({where}\): {REMEDY}"
    assert re.fullmatch(expected, done.stderr.strip()), done.stderr
    assert "Traceback" not in done.stdout + done.stderr
    assert "wrote" not in done.stdout.lower()
    assert _paths(full_disk) == before == {"filler"}


def test_a_sweep_on_a_full_disk_stops_at_once_and_leaves_nothing(
    inputs: Inputs, full_disk: Path
) -> None:
    out, report = full_disk / "sweep", full_disk / "sweep.html"
    sweep = ("-c", "adaptive", "--sweep", "adaptive.a1=5,10,20", "-j", "1")
    done = _hilrig("sweep", str(inputs.session), *sweep, "--out", str(out), "--report", str(report))
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == (  # the first task, run alone: the others never start
        f"error: {FULL}: could not write the results of source s.mcap, run adaptive.a1=5 "
        f"({out}): {REMEDY}"
    )
    assert "Traceback" not in done.stdout + done.stderr
    assert _paths(full_disk) == {"filler"}  # neither sweep.json nor empty partition folders


def _hilrig(*args: str) -> subprocess.CompletedProcess[str]:
    env = os.environ | {"COLUMNS": "400"}  # never a wrapped line
    return subprocess.run(
        [str(HILRIG), *args], capture_output=True, text=True, timeout=300, check=False, env=env
    )
