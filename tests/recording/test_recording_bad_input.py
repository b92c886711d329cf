"""Corrupt chunks are detected and reported; bad inputs give one line naming the file."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import pytest
import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.stream_reader import CRCValidationError
from mcap.writer import Writer as McapWriter
from recording_helpers import Written

from hilrig.errors import RecordingError
from hilrig.recording import inspect, load, read, recover
from hilrig.recording.msgdef import full_definition
from hilrig.recording.schema import TOPICS

CLI = [sys.executable, "-c", "from hilrig.cli import main; main()"]


def middle_chunk(session: Written) -> tuple[int, int, int]:
    """(chunk record offset, data offset, data size) of the third chunk."""
    with open(session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[2]
    data_offset = chunk.chunk_start_offset + chunk.chunk_length - chunk.compressed_size
    return chunk.chunk_start_offset, data_offset, chunk.compressed_size


def corrupted(session: Written, tmp_path: Path, offset: int, name: str) -> Path:
    data = bytearray(session.path.read_bytes())
    data[offset] ^= 0x5A
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def official_messages(path: Path) -> int:
    with open(path, "rb") as f:
        return sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages())


def test_corrupt_chunk_data_is_skipped_and_reported(small_session: Written, tmp_path: Path) -> None:
    offset, data_offset, size = middle_chunk(small_session)
    path = corrupted(small_session, tmp_path, data_offset + size // 2, "bad-data.mcap")
    with pytest.raises((CRCValidationError, McapError, zstandard.ZstdError)):
        official_messages(path)  # the official reader agrees the chunk is bad
    loaded = read(path)
    (problem,) = loaded.problems
    assert problem.startswith(f"{path}: chunk record at bytes {offset}-")
    assert "compressed data is corrupt" in problem
    assert problem.endswith(
        "its messages 2026-01-01T00:00:00.500000000Z to 2026-01-01T00:00:00.749000017Z skipped"
    )
    kept = sum(len(frame) for frame in loaded.frames.values())
    assert 0 < kept < len(small_session.samples)
    with pytest.warns(UserWarning, match="skipped"):
        load(path)
    recovery = recover(path, tmp_path / "fixed.mcap")
    (line,) = recovery.problems
    assert line.startswith(f"{path}: chunk record at bytes {offset}-")
    assert line.endswith(
        "its messages from 2026-01-01T00:00:00.500000000Z to 2026-01-01T00:00:00.749000017Z are"
        " lost: 2252 (/ft/wrist 250, /ft/base 250, /joint_states 250, /controller/input 250,"
        " /controller/state 250, /trajectory/desired 250, /trajectory/commanded 250,"
        " /robot/servo 250, /events 2,"
        " /diagnostics/loop 250)"
    )
    assert kept + 2252 == len(small_session.samples)
    assert recovery.lost == {
        t: 250 for t in TOPICS if t not in ("/events", "/robot_description")
    } | {"/events": 2}
    assert official_messages(tmp_path / "fixed.mcap") == recovery.messages == kept


def test_corrupt_chunk_crc_field_is_found_by_check_and_recover(
    small_session: Written, tmp_path: Path
) -> None:
    offset, _, _ = middle_chunk(small_session)
    crc_at = offset + 9 + 8 + 8 + 8  # opcode, length, start, end, uncompressed size
    path = corrupted(small_session, tmp_path, crc_at, "bad-crc.mcap")
    with pytest.raises(CRCValidationError):
        official_messages(path)
    assert inspect(path).problems == inspect(path, check=True).problems  # the data CRC tells
    described = inspect(path)
    end = offset + 9 + int.from_bytes(path.read_bytes()[offset + 1 : offset + 9], "little")
    assert described.problems == (
        f"{path}: chunk record at bytes {offset}-{end - 1}: its CRC field is damaged; zstd's"
        " own checksum vouches for its data",
    )
    recovery = recover(path, tmp_path / "fixed.mcap")  # keeps the chunk, with its CRC mended
    assert official_messages(tmp_path / "fixed.mcap") == recovery.messages
    assert recovery.messages == len(small_session.samples)
    assert inspect(tmp_path / "fixed.mcap", check=True).problems == ()


def json_only(path: Path) -> Path:
    with open(path, "wb") as f:
        writer = McapWriter(f)
        writer.start(profile="", library="test")
        schema = writer.register_schema("Pose", "jsonschema", b'{"type": "object"}')
        channel = writer.register_channel("/pose", "json", schema)
        writer.add_message(channel, log_time=1, data=b'{"x": 1}', publish_time=1)
        writer.finish()
    return path


def one_message(path: Path, name: str, schema_text: bytes, data: bytes) -> Path:
    with open(path, "wb") as f:
        writer = McapWriter(f)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema(name, "ros2msg", schema_text)
        channel = writer.register_channel("/thing", "cdr", schema)
        writer.add_message(channel, log_time=1, data=data, publish_time=1)
        writer.finish()
    return path


def mismatched(path: Path) -> Path:
    """A WrenchStamped channel whose message is far too short for a WrenchStamped."""
    text = full_definition("geometry_msgs/msg/WrenchStamped").encode()
    return one_message(path, "geometry_msgs/msg/WrenchStamped", text, b"\x00\x01\x00\x00\x07")


def unparsable_schema(path: Path) -> Path:
    return one_message(path, "pkg/msg/Thing", b"@@@@ !!\n", b"\x00\x01\x00\x00" + bytes(8))


BAD_INPUTS = {
    "not-mcap": (lambda p: (p.write_text("time,fx\n0,1\n"), p)[1], "not an MCAP file"),
    "empty": (lambda p: (p.write_bytes(b""), p)[1], "empty file (0 bytes)"),
    "truncated-magic": (lambda p: (p.write_bytes(b"\x89MC"), p)[1], "not an MCAP file"),
    "json-schema": (json_only, "topic /pose has schema encoding 'jsonschema', not ros2msg/cdr"),
    "schema-mismatch": (mismatched, "topic /thing: a message does not match schema"),
    "bad-schema-text": (unparsable_schema, "topic /thing: schema pkg/msg/Thing cannot be parsed"),
}


@pytest.mark.parametrize("kind", sorted(BAD_INPUTS))
def test_bad_input_is_one_line_naming_the_file(tmp_path: Path, kind: str) -> None:
    make, message = BAD_INPUTS[kind]
    path = make(tmp_path / f"{kind}.mcap")
    with pytest.raises(RecordingError) as caught:
        load(path)
    assert str(caught.value).startswith(f"{path}: ")
    assert message in str(caught.value)
    for command in (["export", str(path), "--out", str(tmp_path / "out")], ["info", str(path)]):
        if command[0] == "info" and kind not in ("not-mcap", "empty", "truncated-magic"):
            continue  # info describes any MCAP file, whatever its schemas
        done = subprocess.run([*CLI, *command], capture_output=True, text=True, check=False)
        assert done.returncode == 2
        assert "Traceback" not in done.stderr
        (line,) = done.stderr.splitlines()
        assert line.startswith(f"error: {path}: ")
        assert message in line


def test_missing_file_and_directory_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match=r"nope\.mcap: no such file$"):
        load(tmp_path / "nope.mcap")
    with pytest.raises(RecordingError, match="is a directory"):
        load(tmp_path)


def test_struct_of_the_crc_offset_matches_the_spec() -> None:
    # Guards the byte arithmetic of the CRC test: start, end and size are three u64 fields.
    assert struct.calcsize("<BQQQQ") == 9 + 8 + 8 + 8


def test_a_damaged_metadata_record_is_reported_and_named(
    small_session: Written, tmp_path: Path
) -> None:
    with open(small_session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    ref = summary.metadata_indexes[0]
    data = bytearray(small_session.path.read_bytes())
    map_at = ref.offset + 9 + 4 + len(ref.name.encode())  # opcode, length, name
    data[map_at : map_at + 4] = struct.pack("<I", 0xFFFFFF00)  # the map runs past the record
    path = tmp_path / "bad-metadata.mcap"
    path.write_bytes(bytes(data))
    end = ref.offset + ref.length - 1
    what = f"metadata record 'session' at bytes {ref.offset}-{end}"
    line = f"{path}: {what}: its fields run past its end"
    described = inspect(path)
    assert described.problems == (line,) and not described.complete
    assert "session" not in described.metadata and "calibration" in described.metadata
    with pytest.raises(RecordingError) as caught:
        described.session_info()
    assert str(caught.value) == line
