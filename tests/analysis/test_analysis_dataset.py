"""The partitioned dataset: session metadata columns, replay results, rewriting a partition."""

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from analysis_helpers import paper_replay_frame, write_replay, write_session

from hilrig.analysis import (
    PARTITIONS,
    analyze,
    dataset,
    dataset_frame,
    load_replay,
    load_session,
    read_dataset,
    write_dataset,
)
from hilrig.errors import AnalysisError, RecordingError

PARTITION_FILE = "session_id=__HIVE_DEFAULT_PARTITION__/part-0.parquet"


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


def test_partitions_are_written_all_or_none(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    source = load_replay(_replay_from(tmp_path / "replay.parquet", None))
    frame = dataset_frame([analyze(source)])
    write = dataset.pq.write_table
    calls: list[Path] = []

    def second_fails(table: object, where: Path) -> None:
        calls.append(where)
        if len(calls) == 2:
            raise OSError("disk full")
        write(table, where)

    monkeypatch.setattr(dataset.pq, "write_table", second_fails)
    root = tmp_path / "dataset"
    with pytest.raises(AnalysisError) as caught:
        write_dataset(frame, root)
    assert str(caught.value) == f"{root}: cannot write the dataset (disk full)"
    assert len(calls) == 2 and not root.exists()  # the folders it made are gone too


def test_an_existing_partition_is_replaced_only_when_asked(tmp_path: Path) -> None:
    source = load_replay(_replay_from(tmp_path / "replay.parquet", {"subject_id": "S003"}))
    frame = dataset_frame([analyze(source)])
    root = write_dataset(frame, tmp_path / "dataset")
    part = root / "subject_id=S003" / "controller=adaptive" / PARTITION_FILE
    with pytest.raises(AnalysisError) as caught:
        write_dataset(frame, root)
    assert str(caught.value) == (
        f"{part}: already exists (this session's partition of the dataset); pass --overwrite "
        "to replace it"
    )
    write_dataset(frame.assign(max_abs_offset=1.0), root, overwrite=True)
    assert set(read_dataset(root)["max_abs_offset"]) == {1.0}
    assert len(read_dataset(root)) == len(frame)
