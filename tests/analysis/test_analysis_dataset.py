"""The partitioned dataset: session metadata columns, replay results, rewriting a partition."""

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from analysis_helpers import paper_replay_frame, write_replay, write_session

from hilrig.analysis import (
    PARTITIONS,
    analyze,
    dataset_frame,
    load_replay,
    load_session,
    read_dataset,
    write_dataset,
)
from hilrig.errors import AnalysisError, RecordingError


def _replay_from(path: Path, origin: dict[str, object] | None) -> Path:
    write_replay(path, paper_replay_frame(laws=("adaptive", "fixed"), duration_s=7.0))
    if origin is not None:
        table = pq.read_table(path)
        metadata = {**table.schema.metadata, b"hilrig.input": json.dumps(origin).encode()}
        pq.write_table(table.replace_schema_metadata(metadata), path)
    return path


def test_session_rows_carry_the_session_metadata(tmp_path: Path) -> None:
    path = write_session(tmp_path / "s.mcap", subject_id="S007", session_id="s-7", law="fixed")
    frame = dataset_frame([analyze(load_session(path))])
    assert list(frame.columns[: len(PARTITIONS)]) == list(PARTITIONS)
    first = frame.iloc[0]
    assert (first["subject_id"], first["controller"], first["session_id"]) == (
        "S007",
        "fixed",
        "s-7",
    )
    assert first["start_utc"] == "2026-01-01T00:00:00.000000000Z"
    assert json.loads(first["controller_params"]) == {"preset": "paper"}
    # t_s = 0 is the first controller state, logged at the session start here
    assert first["source_start_ns"] == 1_767_225_600_000_000_000


def test_replay_rows_go_under_the_session_their_input_came_from(tmp_path: Path) -> None:
    origin = {"subject_id": "S003", "session_id": "s-3", "t0_ns": 123}
    source = load_replay(_replay_from(tmp_path / "replay.parquet", origin))
    assert (source.subject_id, source.session_id, source.start_ns) == ("S003", "s-3", 123)
    root = write_dataset(dataset_frame([analyze(source)]), tmp_path / "dataset")
    assert sorted(p.name for p in (root / "subject_id=S003").iterdir()) == [
        "controller=adaptive",
        "controller=fixed",
    ]
    frame = read_dataset(root)
    assert set(frame["session_id"]) == {"s-3"}
    assert frame["rig"].isna().all()


def test_replay_rows_without_an_origin_have_null_partitions(tmp_path: Path) -> None:
    source = load_replay(_replay_from(tmp_path / "replay.parquet", None))
    root = write_dataset(dataset_frame([analyze(source)]), tmp_path / "dataset")
    assert (root / "subject_id=__HIVE_DEFAULT_PARTITION__").is_dir()
    frame = read_dataset(root)
    assert frame["subject_id"].isna().all() and frame["session_id"].isna().all()
    assert set(frame["controller"]) == {"adaptive", "fixed"}


def test_a_replay_naming_a_subject_is_refused(tmp_path: Path) -> None:
    path = _replay_from(tmp_path / "replay.parquet", {"subject_id": "Jane Doe"})
    with pytest.raises(RecordingError, match="personal names must never be recorded"):
        load_replay(path)


def test_the_dataset_goes_in_a_folder(tmp_path: Path) -> None:
    source = load_replay(_replay_from(tmp_path / "replay.parquet", None))
    (tmp_path / "file").write_text("")
    with pytest.raises(AnalysisError, match="this is a file"):
        write_dataset(dataset_frame([analyze(source)]), tmp_path / "file")
