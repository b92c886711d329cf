"""Session ids: unique and in minting order whatever the clock does, apart in a forked child,
valid file names and hive partition values; a split part's file names its session's."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
from hypothesis import given
from hypothesis import strategies as st

from hilrig.analysis.dataset import PARTITIONS
from hilrig.recording.session_ids import SessionIds, new_session_id, written_as
from hilrig.recording.writer import part_path

CROCKFORD = r"[0-9A-HJKMNP-TV-Z]{26}"
MAX_MS = 2**48 - 1  # a ULID's 48 bits of milliseconds


@given(st.lists(st.integers(0, MAX_MS), min_size=1, max_size=60))
def test_ids_minted_in_sequence_are_unique_and_sort_in_minting_order(readings: list[int]) -> None:
    clock = iter(readings)  # any clock: repeated milliseconds, steps back, jumps
    ids = SessionIds(lambda: next(clock))
    minted = [ids.mint() for _ in readings]
    assert len(set(minted)) == len(minted)
    assert sorted(minted) == minted
    assert all(re.fullmatch(CROCKFORD, i) for i in minted)


def test_the_ids_of_this_process_sort_in_minting_order() -> None:
    minted = [new_session_id() for _ in range(2000)]  # many within one millisecond
    assert len(set(minted)) == len(minted) and sorted(minted) == minted


def test_a_forked_child_never_mints_its_parents_next_id() -> None:
    ids = SessionIds(lambda: 1_800_000_000_000)  # one millisecond for ever: ids only count up
    ids.mint()
    read, write = os.pipe()
    child = os.fork()
    if child == 0:  # the child: its next id, to the parent
        os.write(write, ids.mint().encode())
        os._exit(0)
    os.close(write)
    with os.fdopen(read, "rb") as pipe:
        childs = pipe.read().decode()
    _, status = os.waitpid(child, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    parents = ids.mint()
    assert re.fullmatch(CROCKFORD, childs) and childs != parents


def test_an_id_is_a_hive_partition_value_as_it_is() -> None:
    session_id = new_session_id()
    hive = ds.partitioning(pa.schema([(n, pa.string()) for n in PARTITIONS]), flavor="hive")
    condition = pc.field("subject_id") == "S001"
    condition &= pc.field("controller") == "adaptive"
    condition &= pc.field("session_id") == session_id
    folder, _ = hive.format(condition)
    assert folder == f"subject_id=S001/controller=adaptive/session_id={session_id}"


@given(
    st.from_regex(r"[a-z][a-z0-9_-]{0,12}(/[a-z][a-z0-9_.-]{0,12})?", fullmatch=True),
    st.integers(0, 999),
)
def test_a_split_parts_file_names_the_file_its_session_was_written_to(stem: str, part: int) -> None:
    written = Path(f"{stem}.mcap")
    assert written_as(part_path(written, part).as_posix(), part) == written.as_posix()


def test_a_file_not_named_as_a_part_is_its_own() -> None:
    assert written_as("S001/run.mcap", 0) == "S001/run.mcap"
    assert written_as("S001/run_001.mcap", 2) == "S001/run_001.mcap"  # part 2's name is _002
    assert written_as("S001/run_002.mcap", 2) == "S001/run.mcap"
