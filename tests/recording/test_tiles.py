"""The compiled check that a chunk's message index tiles it, against the chunk's records walked
one by one (the oracle): true for every chunk hilrig writes, false for any wrong entry."""

from __future__ import annotations

import numpy as np
from recording_helpers import Written

from hilrig.recording.chunks import entries_of, indexed_entries, inflate, scan_entries
from hilrig.recording.scan import index_mapped, open_mcap


def chunks_and_indexes(session: Written) -> list[tuple[bytes, dict]]:
    path, mm = open_mcap(session.path)
    index = index_mapped(path, mm)
    found = []
    for chunk in index.chunks:
        data, _ = inflate(mm, chunk)
        found.append((data, indexed_entries(mm, chunk)))
    return found


def test_every_index_the_writer_made_tiles_its_chunk(small_session: Written) -> None:
    for data, hint in chunks_and_indexes(small_session):
        walked, _ = scan_entries(data)
        entries, _, wrong = entries_of(data, hint)
        assert entries is hint and not wrong  # taken as it is: it tiles
        for cid, (times, offsets) in walked.items():  # and it is what the walk finds
            np.testing.assert_array_equal(hint[cid][0], times)
            np.testing.assert_array_equal(hint[cid][1], offsets)


def test_a_wrong_entry_does_not_tile_and_the_chunk_is_walked(small_session: Written) -> None:
    data, hint = chunks_and_indexes(small_session)[0]
    walked, _ = scan_entries(data)
    cid = next(iter(hint))
    times, offsets = hint[cid]
    for bad in (
        (times + np.eye(len(times), dtype=np.int64)[-1], offsets),  # one log time off by 1 ns
        (times, np.sort(offsets + np.eye(len(offsets), dtype=np.int64)[0])),  # one offset
        (times[:-1], offsets[:-1]),  # a message left out
    ):
        entries, _, wrong = entries_of(data, {**hint, cid: bad})
        assert wrong and set(entries) == set(walked)
        np.testing.assert_array_equal(entries[cid][1], walked[cid][1])
    other = next(c for c in hint if c != cid)
    swapped = {**hint, cid: hint[other], other: hint[cid]}  # entries under the wrong channel
    assert entries_of(data, swapped)[2]
