"""One way to write outputs: all or nothing, nothing existing touched, nothing left behind."""

import os
import re
import stat
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.errors import OutputError
from hilrig.outputs import check_new_file, new_files


def listing(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>"
        for p in sorted(folder.rglob("*"))
    }


def test_files_appear_only_when_the_block_completes(tmp_path: Path) -> None:
    a, b = tmp_path / "a.parquet", tmp_path / "b.mcap"
    with new_files(a, b) as (ta, tb):
        assert ta.parent == tmp_path and ta.suffix == ".parquet" and ta.name.startswith(".a.")
        ta.write_bytes(b"A")
        tb.write_bytes(b"B")
        assert not a.exists() and not b.exists()
    assert listing(tmp_path) == {"a.parquet": b"A", "b.mcap": b"B"}


def test_an_existing_output_is_refused_before_any_work(tmp_path: Path) -> None:
    kept = tmp_path / "replay.parquet"
    kept.write_bytes(b"a replay result")
    with pytest.raises(OutputError) as caught, new_files(tmp_path / "new.csv", kept):
        pytest.fail("the block must not run")
    assert str(caught.value) == f"{kept}: already exists; refusing to overwrite it"
    assert listing(tmp_path) == {"replay.parquet": b"a replay result"}


def test_overwrite_replaces_a_regular_file_but_never_a_folder_or_device(tmp_path: Path) -> None:
    old = tmp_path / "t.csv"
    old.write_bytes(b"old")
    with new_files(old, overwrite=True) as (t,):
        t.write_bytes(b"new")
    assert old.read_bytes() == b"new"
    (tmp_path / "d").mkdir()
    with pytest.raises(OutputError, match=re.escape("exists and is not a regular file")):
        check_new_file(tmp_path / "d", overwrite=True)
    with pytest.raises(OutputError) as caught:
        check_new_file(Path("/dev/null"), overwrite=True)
    assert str(caught.value) == (
        "/dev/null: exists and is not a regular file; refusing to write there"
    )


def test_missing_and_read_only_folders_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(OutputError) as caught:
        check_new_file(tmp_path / "nope" / "x.csv")
    assert (
        str(caught.value)
        == f"{tmp_path / 'nope' / 'x.csv'}: folder {tmp_path / 'nope'} does not exist"
    )
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        if os.access(locked, os.W_OK):
            pytest.skip("running as root: permissions do not bind")
        with pytest.raises(OutputError) as caught:
            check_new_file(locked / "x.csv")
        assert str(caught.value) == f"{locked / 'x.csv'}: folder {locked} is not writable"
    finally:
        locked.chmod(stat.S_IRWXU)


def test_the_same_output_twice_is_refused(tmp_path: Path) -> None:
    with (
        pytest.raises(OutputError, match="the same output is named twice"),
        new_files(tmp_path / "a", tmp_path / "a"),
    ):
        pytest.fail("the block must not run")


def test_created_folders_are_removed_after_a_failure(tmp_path: Path) -> None:
    out = tmp_path / "demo" / "sub" / "table.csv"
    with pytest.raises(RuntimeError), new_files(out, create_folders=True) as (t,):
        t.write_bytes(b"half")
        raise RuntimeError("the writer failed")
    assert listing(tmp_path) == {}


def test_an_output_that_appears_meanwhile_is_not_replaced_and_nothing_is_left(
    tmp_path: Path,
) -> None:
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    with pytest.raises(OutputError) as caught, new_files(a, b) as (ta, tb):
        ta.write_bytes(b"A")
        tb.write_bytes(b"B")
        b.write_bytes(b"someone else's")
    assert str(caught.value) == f"{b}: appeared while writing; refusing to overwrite it"
    assert listing(tmp_path) == {"b.csv": b"someone else's"}  # a was taken back out


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 4),
    written=st.integers(0, 4),
    fail=st.booleans(),
    existing=st.sets(st.integers(0, 3), max_size=2),
)
def test_any_failure_leaves_the_folder_as_it_was(
    tmp_path_factory: pytest.TempPathFactory, n: int, written: int, fail: bool, existing: set[int]
) -> None:
    folder = tmp_path_factory.mktemp("out")
    for i in existing:
        (folder / f"keep{i}.bin").write_bytes(b"kept %d" % i)
    before = listing(folder)
    outs = [folder / f"out{i}.bin" for i in range(n)]
    try:
        with new_files(*outs) as temporaries:
            for t in temporaries[:written]:
                t.write_bytes(b"data")
            if fail:
                raise KeyError("boom")
    except (KeyError, OutputError):
        assert listing(folder) == before
    else:
        assert written >= n and not fail
        assert listing(folder) == before | {f"out{i}.bin": b"data" for i in range(n)}


def test_a_path_below_a_file_names_the_file(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_bytes(b"x")
    for create in (False, True):
        with pytest.raises(OutputError) as caught:
            check_new_file(afile / "new" / "s.mcap", create_folder=create)
        assert str(caught.value) == f"{afile / 'new' / 's.mcap'}: {afile} is not a folder"
    with pytest.raises(OutputError) as caught:
        check_new_file(afile / "s.mcap")
    assert str(caught.value) == f"{afile / 's.mcap'}: {afile} is not a folder"
