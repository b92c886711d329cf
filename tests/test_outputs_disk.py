"""A disk that refuses an output (full, over quota, past a file's largest size, failing) is an
expected failure: one line saying what could not be written, where, and what to do; nothing left.

Full disks of every writing command are in tests/cli/test_cli_disk_full.py (a real tmpfs);
here each kind of refusal, as a writer or a library reports it, and a real EFBIG."""

from __future__ import annotations

import errno
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from test_outputs import listing

from hilrig.cli.errors import disk_error
from hilrig.errors import DiskError
from hilrig.outputs import DISK_ERRORS, new_files

HILRIG = Path(sys.executable).with_name("hilrig")
EXAMPLE = Path(__file__).parents[1] / "recordings" / "example-paper-end-effector.mcap"
LIMIT_BYTES = 65536  # the example recording is larger
EXPECTED = {
    errno.ENOSPC: "the disk is full: could not write {what} ({where}): nothing was written; "
    "free space and run again",
    errno.EDQUOT: "the disk quota is exceeded: could not write {what} ({where}): nothing was "
    "written; free space (or raise the quota) and run again",
    errno.EFBIG: "a file is larger than allowed (by its file system, or the process's limit): "
    "could not write {what} ({where}): nothing was written; write it elsewhere (or raise the "
    "limit) and run again",
    errno.EIO: "the disk failed to write (I/O error): could not write {what} ({where}): nothing "
    "was written; check the disk and run again",
}


@pytest.mark.parametrize("code", sorted(DISK_ERRORS), ids=errno.errorcode.get)
def test_a_refused_write_is_one_line_and_leaves_the_folder_as_it_was(
    tmp_path: Path, code: int
) -> None:
    (tmp_path / "kept.csv").write_bytes(b"an earlier output")
    before = listing(tmp_path)
    outs = (tmp_path / "new" / "a.parquet", tmp_path / "new" / "b.parquet")
    with pytest.raises(DiskError) as caught, new_files(*outs, create_folders=True) as (ta, tb):
        ta.write_bytes(b"whole")
        tb.write_bytes(b"half")
        raise OSError(code, os.strerror(code))  # the write of the rest
    assert str(caught.value) == EXPECTED[code].format(what="2 files", where=tmp_path / "new")
    assert listing(tmp_path) == before


@pytest.mark.parametrize(
    ("raised", "code"),
    [
        (RuntimeError("Failed to write: Disk quota exceeded (os error 122)"), errno.EDQUOT),
        (OSError("[Errno 28] Error writing bytes to file. Detail: [errno 28] ..."), errno.ENOSPC),
        (ValueError("cannot write the table: Input/output error"), errno.EIO),
    ],
    ids=["Rerun", "Arrow", "text"],
)
def test_a_library_s_error_is_read_for_its_cause(
    tmp_path: Path, raised: Exception, code: int
) -> None:
    out = tmp_path / "t.csv"
    with pytest.raises(DiskError) as caught, new_files(out) as (t,):
        t.write_bytes(b"half")
        raise raised
    assert str(caught.value) == EXPECTED[code].format(what="t.csv", where=tmp_path)
    assert caught.value.__cause__ is raised
    assert listing(tmp_path) == {}


def test_a_cause_wrapped_in_another_error_is_found(tmp_path: Path) -> None:
    with pytest.raises(DiskError) as caught, new_files(tmp_path / "r.html") as (t,):
        try:
            t.write_bytes(b"half")
            raise OSError(errno.ENOSPC, "No space left on device", str(t))
        except OSError as err:
            raise ValueError("cannot write the report") from err
    assert str(caught.value).startswith("the disk is full: could not write r.html (")


@pytest.mark.parametrize(
    "raised",
    [
        OSError(errno.EACCES, "Permission denied"),
        RuntimeError("errno 2: no such file"),
        KeyError("boom"),
    ],
    ids=["EACCES", "ENOENT", "other"],
)
def test_other_errors_pass_unchanged(tmp_path: Path, raised: Exception) -> None:
    with pytest.raises(type(raised)) as caught, new_files(tmp_path / "t.csv") as (t,):
        t.write_bytes(b"half")
        raise raised
    assert caught.value is raised
    assert listing(tmp_path) == {}


def test_a_refusal_outside_new_files_is_still_one_line() -> None:
    raised = OSError(errno.ENOSPC, "No space left on device", "/data/S012.mcap")
    disk = disk_error(RuntimeError("the writer stopped"))
    assert disk is None
    disk = disk_error(raised)
    assert disk is not None
    assert (
        str(disk) == "the disk is full: could not write /data/S012.mcap; free space and run again"
    )
    assert disk.__cause__ is raised


def test_a_file_over_the_process_s_size_limit_is_a_real_efbig(tmp_path: Path) -> None:
    assert EXAMPLE.stat().st_size > LIMIT_BYTES
    out = tmp_path / "out"
    out.mkdir()

    def limit() -> None:  # write(2) then fails with EFBIG rather than SIGXFSZ killing it
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))

    done = subprocess.run(
        [str(HILRIG), "recover", str(EXAMPLE), "-o", str(out / "r.mcap")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        preexec_fn=limit,
        env=os.environ | {"COLUMNS": "400"},
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == "error: " + EXPECTED[errno.EFBIG].format(what="r.mcap", where=out)
    assert listing(out) == {}
