"""Files cut short anywhere in their last chunks: every complete chunk loads, the loss is
reported, and ``recover`` writes a file the official reader accepts in full."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from mcap.reader import make_reader
from recording_helpers import Written

from hilrig.recording import read, recover


def official_count(path: Path) -> int:
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        count = sum(1 for _ in reader.iter_messages())
        assert count == summary.statistics.message_count
        return count


def cut_offsets(session: Written) -> list[int]:
    """About 70 cut points from the start of the second-last chunk to the end of the file."""
    with open(session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    start, size = chunks[-2].chunk_start_offset, session.path.stat().st_size
    step = max(1, (size - start) // 60)
    edges = [c.chunk_start_offset + c.chunk_length for c in chunks[-2:]]
    offsets = {*range(start, size, step), *edges, *(e - 1 for e in edges), *(e + 1 for e in edges)}
    return sorted(offsets)


def test_cut_files_load_complete_chunks_and_recover(small_session: Written, tmp_path: Path) -> None:
    data = small_session.path.read_bytes()
    with open(small_session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    log_times = sorted(small_session.log_ns(s) for _, s in small_session.samples)
    for cut in cut_offsets(small_session):
        source, repaired = tmp_path / f"cut{cut}.mcap", tmp_path / f"fixed{cut}.mcap"
        source.write_bytes(data[:cut])
        complete = [c for c in chunks if c.chunk_start_offset + c.chunk_length <= cut]
        expected = sum(1 for t in log_times if t <= complete[-1].message_end_time)
        loaded = read(source)
        assert sum(len(frame) for frame in loaded.frames.values()) == expected, cut
        assert loaded.problems, cut  # always says the file is unfinished or damaged
        recovery = recover(source, repaired)
        assert recovery.messages == expected == official_count(repaired), cut
        source.unlink()
        repaired.unlink()


def test_report_names_the_lost_time_span(small_session: Written, tmp_path: Path) -> None:
    with open(small_session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    last = max(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(small_session.path.read_bytes()[: last.chunk_start_offset + 100])
    (problem,) = read(cut).problems
    assert problem.startswith(f"{cut}: unfinished recording (no summary); 4 complete chunks kept")
    assert "(0.199 s)" in problem  # the incomplete chunk's messages, from its header


CHILD = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {helpers!r})
    from recording_helpers import samples, session_info
    from hilrig.recording import SessionWriter, default_channels
    writer = SessionWriter({path!r}, session_info(), channels=default_channels())
    for topic, sample in samples({ticks}):
        writer.write(topic, sample)
    print("written", flush=True)
    time.sleep(60)
    """
)


@pytest.mark.parametrize("ticks", [260, 731, 1000])
def test_killed_writer_loses_at_most_half_a_second(tmp_path: Path, ticks: int) -> None:
    path = tmp_path / "killed.mcap"
    code = CHILD.format(helpers=str(Path(__file__).parent), path=str(path), ticks=ticks)
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    assert child.stdout.readline() == "written\n"
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    last_written_ns = 1_767_225_600_000_000_000 + (ticks - 1) * 1_000_000 + 17
    loaded = read(path)
    assert "unfinished recording" in loaded.problems[0]
    kept = max(frame.index.max() for frame in loaded.frames.values() if len(frame))
    assert last_written_ns - kept <= 500_000_000
    repaired = tmp_path / "repaired.mcap"
    cli = [sys.executable, "-c", "from hilrig.cli import main; main()"]
    done = subprocess.run(
        [*cli, "recover", str(path), "-o", str(repaired)], capture_output=True, text=True
    )
    assert done.returncode == 1  # written; the source was unfinished
    assert "kept" in done.stdout and "unfinished recording" in done.stdout
    assert official_count(repaired) == sum(len(frame) for frame in loaded.frames.values()) > 0
