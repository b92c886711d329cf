"""Issue 12's cases, one by one: a flipped byte in the session record, impossible times,
twenty flipped bytes mid-file, the loop's counters in ``info``, and where outputs go.

Each names the damage exactly (file, record, byte range, what is wrong, what it cost); every
command either works on what is intact or fails in one line, and leaves nothing behind.
"""

from __future__ import annotations

import json
import random
import re
import warnings
from pathlib import Path

import pandas as pd
import pytest
from fuzz_helpers import hilrig, official_messages
from mcap.reader import make_reader
from recording_helpers import Written, session_info

from hilrig.errors import DiskError, RecordingError
from hilrig.recording import (
    LoopTiming,
    RecordingWarning,
    SessionWriter,
    default_channels,
    export,
    inspect,
    load,
    recover,
)
from hilrig.recording.session import utc_iso

EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"


def summary_of(path: Path):  # type: ignore[no-untyped-def]
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return summary


def changed(session: Written, tmp_path: Path, flips: dict[int, int], name: str) -> Path:
    data = bytearray(session.path.read_bytes())
    for offset, mask in flips.items():
        data[offset] ^= mask
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def loaded_with_warnings(path: Path) -> tuple[dict[str, pd.DataFrame], list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames = load(path)
    assert all(issubclass(w.category, RecordingWarning) for w in caught)
    return frames, [str(w.message) for w in caught]


SESSION_FLIPS = {
    "a digit of the subject id (S012 -> S002, still a pseudonym)": (
        b"S012",
        1,
        0x03,
        "its CRC (key hilrig.crc32) does not match",
    ),
    "a byte of the session id that is no longer UTF-8": (
        b"2026-01-01-S012-a",
        4,
        0xC0,
        "a string in it is not UTF-8",
    ),
}


@pytest.mark.parametrize("case", sorted(SESSION_FLIPS))
def test_a_flipped_byte_in_the_session_record_is_named_by_every_command(
    small_session: Written, tmp_path: Path, case: str
) -> None:
    text, at, mask, detail = SESSION_FLIPS[case]
    ref = next(m for m in summary_of(small_session.path).metadata_indexes if m.name == "session")
    offset = small_session.path.read_bytes().index(text, ref.offset) + at
    path = changed(small_session, tmp_path, {offset: mask}, "flipped.mcap")
    end = ref.offset + ref.length - 1
    line = f"{path}: metadata record 'session' at bytes {ref.offset}-{end}: {detail}"

    described = inspect(path)
    assert described.problems == (line,) and not described.complete
    assert set(described.metadata) == {"calibration", "rosbag2"}
    with pytest.raises(RecordingError, match=re.escape(line)):
        described.session_info()
    info = hilrig("info", str(path))
    assert info.exit_code == 1 and info.stderr == f"warning: {line}\n"
    assert "DAMAGED" in info.stdout and "complete" not in info.stdout
    assert hilrig("info", "--check", str(path)).stderr == f"warning: {line}\n"

    frames, problems = loaded_with_warnings(path)
    assert problems == [line]
    for topic, frame in load(small_session.path).items():
        pd.testing.assert_frame_equal(frames[topic], frame)

    view = tmp_path / "view.rrd"
    for args in (["replay", "-c", "fixed"], ["analyze"], ["view", "--save", str(view)]):
        run = hilrig(args[0], str(path), *args[1:])
        assert (run.exit_code, run.stderr) == (2, f"error: {line}\n"), args
    assert not view.exists()

    tables = tmp_path / "tables"
    exported = hilrig("export", str(path), "--out", str(tables))
    assert exported.exit_code == 1 and exported.stderr == f"warning: {line}\n"
    assert set(json.loads((tables / "metadata.json").read_text())) == {"calibration", "rosbag2"}

    out = tmp_path / "recovered.mcap"
    recovered = hilrig("recover", str(path), "-o", str(out))
    assert recovered.exit_code == 1
    assert recovered.stdout.splitlines() == [
        f"wrote {out}",
        f"kept {len(small_session.samples)} messages in 5 chunks, from"
        " 2026-01-01T00:00:00.000000000Z to 2026-01-01T00:00:01.199000017Z",
        line,
    ]
    assert official_messages(out) == official_messages(small_session.path)
    assert {m.name for m in summary_of(out).metadata_indexes} == {"calibration", "rosbag2"}
    assert inspect(out, check=True).problems == ()


def test_a_message_index_time_out_of_its_chunk_is_damage_not_a_date(
    small_session: Written, tmp_path: Path
) -> None:
    """The tester's "from 1915": a damaged time in a message index is never shown."""
    chunk = sorted(
        summary_of(small_session.path).chunk_indexes, key=lambda c: c.chunk_start_offset
    )[2]
    index_at = chunk.message_index_offsets[1]
    first_log_time = index_at + 9 + 2 + 4  # opcode, length, channel id, entries' size
    path = changed(small_session, tmp_path, {first_log_time + 7: 0x80}, "bad-index.mcap")
    line = (
        f"{path}: message index records of the chunk at byte {chunk.chunk_start_offset}: message"
        f" index record at byte {index_at}: an entry's log time is outside the chunk's time range"
    )
    described = inspect(path)
    assert described.problems == (line,)
    whole = inspect(small_session.path)
    assert (described.start_ns, described.end_ns) == (whole.start_ns, whole.end_ns)
    assert [t.count for t in described.topics] == [t.count for t in whole.topics]
    info = hilrig("info", str(path))
    assert info.exit_code == 1 and info.stderr == f"warning: {line}\n"
    assert "from 2026-01-01T00:00:00.000000000Z to 2026-01-01T00:00:01.199000017Z" in info.stdout

    frames, problems = loaded_with_warnings(path)
    assert problems == [line]
    assert sum(map(len, frames.values())) == len(small_session.samples)
    recovery = recover(path, tmp_path / "recovered.mcap")
    assert recovery.problems == (line,) and recovery.messages == len(small_session.samples)
    assert official_messages(tmp_path / "recovered.mcap") == official_messages(small_session.path)


def test_an_impossible_chunk_time_in_an_unfinished_file_is_mended(
    small_session: Written, tmp_path: Path
) -> None:
    chunks = sorted(
        summary_of(small_session.path).chunk_indexes, key=lambda c: c.chunk_start_offset
    )
    second, cut = chunks[1], chunks[3].chunk_start_offset + 100
    source = tmp_path / "cut.mcap"
    data = bytearray(small_session.path.read_bytes()[:cut])
    data[second.chunk_start_offset + 9 + 7] ^= 0x80  # the top byte of its start time
    source.write_bytes(bytes(data))
    end = second.chunk_start_offset + second.chunk_length - 1
    start = second.message_start_time ^ (0x80 << 56)
    problems = inspect(source).problems
    assert problems[0].startswith(f"{source}: unfinished recording (no summary); 3 complete")
    assert problems[1] == (
        f"{source}: chunk record at bytes {second.chunk_start_offset}-{end}: impossible log"
        f" times {utc_iso(start)} to 2026-01-01T00:00:00.499000017Z (the session started at"
        " 2026-01-01T00:00:00.000000000Z: within 1 h before and 7 days after it)"
    )
    assert len(problems) == 2
    recovery = recover(source, tmp_path / "recovered.mcap")
    assert recovery.start_ns == 1_767_225_600_000_000_000
    mended = summary_of(tmp_path / "recovered.mcap").chunk_indexes[1]
    assert (mended.message_start_time, mended.message_end_time) == (
        second.message_start_time,
        second.message_end_time,
    )
    kept = official_messages(tmp_path / "recovered.mcap")
    last = chunks[2].message_end_time
    expected = sum(1 for _, s in small_session.samples if small_session.log_ns(s) <= last)
    assert not kept - official_messages(small_session.path) and sum(kept.values()) == expected


def test_twenty_flipped_bytes_mid_file_lose_only_their_chunks(
    small_session: Written, tmp_path: Path
) -> None:
    size = small_session.path.stat().st_size
    rng = random.Random(12)
    flips = {rng.randrange(size // 3, 2 * size // 3): rng.randrange(1, 256) for _ in range(20)}
    path = changed(small_session, tmp_path, flips, "twenty.mcap")
    at = rf"^{re.escape(str(path))}: "
    chunk_line = re.compile(
        at + r"(chunk record at bytes \d+-\d+: compressed data is corrupt \(.+\); its messages"
        r" from \S+Z to \S+Z are lost: (at least )?\d+ \((/\S+ \d+)(, /\S+ \d+)*\)"
        r"|message index record at bytes \d+-\d+: .+"
        r"|message index records of the chunk at byte \d+: message index record at byte \d+: .+)$"
    )
    for check in ([], ["--check"]):
        info = hilrig("info", *check, str(path))
        assert info.exit_code == 1 and "complete" not in info.stdout
        lines = info.stderr.removeprefix("warning: ").split("\nwarning: ")
        assert lines and all(chunk_line.match(line.strip()) for line in lines), lines
    recovered = hilrig("recover", str(path), "-o", str(tmp_path / "r.mcap"))
    assert recovered.exit_code == 1 and "nothing was lost" not in recovered.stdout
    problems = recovered.stdout.splitlines()[2:]
    assert all(chunk_line.match(p) or p.startswith("messages lost per topic: ") for p in problems)
    kept = official_messages(tmp_path / "r.mcap")
    assert not kept - official_messages(small_session.path)


def test_info_shows_the_loop_counters(tmp_path: Path) -> None:
    path = tmp_path / "loop.mcap"
    with SessionWriter(path, session_info(), channels=default_channels()) as writer:
        for i in range(120):
            t = 5_000_000_000 + i * 1_000_000
            writer.write(
                "/diagnostics/loop", LoopTiming(t, i + 1, 1_000_000, 90_000, 0, i // 40, i // 17)
            )
    info = hilrig("info", str(path))
    assert info.exit_code == 0
    line = (
        "loop: 2 overruns and 7 recorder drops by tick 120; hold ticks unknown: no outcome"
        " record: the session did not end cleanly, or an older hilrig wrote it"
    )
    assert line in info.stdout.splitlines()
    counters = inspect(path).loop
    assert counters is not None and (counters.tick, counters.overruns, counters.recorder_drops) == (
        120,
        2,
        7,
    )


def test_export_refuses_existing_tables_unless_overwrite(
    small_session: Written, tmp_path: Path
) -> None:
    out = tmp_path / "new" / "tables"  # made, with its parent
    assert hilrig("export", str(small_session.path), "--out", str(out)).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    again = hilrig("export", str(small_session.path), "--out", str(out))
    assert (again.exit_code, again.stderr) == (
        2,
        f"error: {out}/metadata.json: already exists; refusing to overwrite it\n",
    )
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    replaced = hilrig("export", str(small_session.path), "--out", str(out), "--overwrite")
    assert replaced.exit_code == 0 and sorted(p.name for p in out.iterdir()) == sorted(before)


def test_export_onto_a_file_and_recover_into_nowhere_are_one_line(
    small_session: Written, tmp_path: Path
) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("x")
    run = hilrig("export", str(small_session.path), "--out", str(a_file))
    assert run.stderr == f"error: {a_file}/metadata.json: {a_file} is not a folder\n"
    missing = tmp_path / "missing" / "out.mcap"
    run = hilrig("recover", str(small_session.path), "-o", str(missing))
    assert run.stderr == f"error: {missing}: folder {missing.parent} does not exist\n"
    run = hilrig("recover", str(small_session.path), "-o", str(a_file))
    assert run.stderr == f"error: {a_file}: already exists; refusing to overwrite it\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_a_failed_export_leaves_nothing(
    small_session: Written, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import pyarrow.parquet as pq

    calls = []
    real = pq.write_table

    def fill_the_disk(table: object, where: object, **options: object) -> None:
        calls.append(where)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        real(table, where, **options)

    monkeypatch.setattr(pq, "write_table", fill_the_disk)
    out = tmp_path / "tables"
    with pytest.raises(DiskError) as caught:
        export(small_session.path, out)
    assert re.fullmatch(
        rf"the disk is full: could not write \d+ files \({re.escape(str(out))}\): nothing was "
        "written; free space and run again",
        str(caught.value),
    )
    assert not out.exists()


def test_flips_in_the_example_recordings_session_record_are_reported(tmp_path: Path) -> None:
    """The example predates the CRC seals: a changed value may pass, a broken record may not
    crash anything."""
    data = EXAMPLE.read_bytes()
    ref = next(m for m in summary_of(EXAMPLE).metadata_indexes if m.name == "session")
    rng = random.Random(500)
    path = tmp_path / "example.mcap"
    for offset in sorted(rng.sample(range(ref.offset, ref.offset + ref.length), 12)):
        damaged = bytearray(data)
        damaged[offset] ^= rng.randrange(1, 256)
        path.write_bytes(bytes(damaged))
        described = inspect(path)
        assert all(p.startswith(f"{path}: ") for p in described.problems)
        try:
            session = described.session_info()
        except RecordingError as err:
            assert str(err).startswith(f"{path}: metadata record 'session' at bytes {ref.offset}-")
        else:
            assert session is not None  # a value changed and no check can tell
        out = tmp_path / "recovered.mcap"
        recovery = recover(path, out)
        assert not recovery.was_complete or not described.problems
        assert sum(official_messages(out).values()) == recovery.messages
        out.unlink()


def test_a_damaged_size_field_loses_nothing(small_session: Written, tmp_path: Path) -> None:
    """zstd's frame carries its own size and checksum: recover keeps the chunk, mended."""
    chunks = sorted(
        summary_of(small_session.path).chunk_indexes, key=lambda c: c.chunk_start_offset
    )
    second = chunks[1]
    source = tmp_path / "cut.mcap"  # cut, so that no summary repeats the size
    data = bytearray(small_session.path.read_bytes()[: chunks[3].chunk_start_offset])
    data[second.chunk_start_offset + 9 + 16 + 1] ^= 0x01  # its uncompressed size
    source.write_bytes(bytes(data))
    end = second.chunk_start_offset + second.chunk_length - 1
    recovery = recover(source, tmp_path / "recovered.mcap")
    assert recovery.problems[1:] == (
        f"{source}: chunk record at bytes {second.chunk_start_offset}-{end}: its size field is"
        " damaged; zstd's own checksum vouches for its data",
    )
    last = chunks[2].message_end_time
    expected = sum(1 for _, s in small_session.samples if small_session.log_ns(s) <= last)
    assert recovery.messages == expected == sum(official_messages(recovery.output).values())
