"""The catalogue: every session described from its metadata, checked against the official
``mcap`` reader; re-indexing reads only new or changed files; quality flags."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest
from mcap.reader import make_reader
from study_helpers import write_study, write_study_session

from hilrig.errors import StudyError
from hilrig.study.catalogue import (
    CATALOGUE_COLUMNS,
    conditions,
    index,
    recordings,
    sessions,
    settings_columns,
)

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from analysis_helpers import write_session

SUBJECTS = ("S001", "S002", "S003")
LAWS = ("adaptive", "fixed")


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("study")
    write_study(root, SUBJECTS, LAWS, duration_s=6.0)
    return root


def _copy(study: Path, tmp_path: Path) -> Path:
    root = tmp_path / "copy"
    shutil.copytree(study, root, ignore=shutil.ignore_patterns(".hilrig-study"))
    return root


def _official(path: Path) -> dict[str, dict[str, str]]:
    """The file's metadata records, read by the official mcap reader."""
    with path.open("rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


def _events(path: Path) -> int:
    """The file's /events messages (the helper writes collision starts only), officially."""
    with path.open("rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages(topics=["/events"]))


def test_every_session_is_described_as_the_official_reader_reads_its_metadata(
    study: Path,
) -> None:
    catalogue = sessions(index(study)[0])
    assert list(catalogue.columns) == list(CATALOGUE_COLUMNS)
    assert len(catalogue) == len(SUBJECTS) * len(LAWS)
    for row in catalogue.itertuples(index=False):
        records = _official(study / row.path)
        session, outcome = records["session"], records["outcome"]
        assert row.session == session["session_id"]
        assert row.subject == session["subject_id"]
        assert row.controller == session["controller"] == row.condition
        assert json.loads(row.settings) == json.loads(session["scenario_settings"])
        assert row.body_region == session["body_region"] == "hand"
        assert row.ticks == int(outcome["ticks"])
        assert row.dropped == int(outcome["recorder_drops"]) == 0
        assert row.collisions == _events(study / row.path) == 1
        assert row.flags == "" and row.complete and row.ended_cleanly
        assert row.start_utc == session["start_utc"]
        assert row.duration_s == pytest.approx(6.0, abs=0.01)


def test_re_indexing_reads_only_new_or_changed_files(study: Path, tmp_path: Path) -> None:
    root = _copy(study, tmp_path)
    assert index(root)[1] == 6
    assert index(root)[1] == 0
    write_study_session(
        root / "S004" / "S004-fixed.mcap",
        subject="S004",
        law="fixed",
        scale=2.0,
        session_id="S004-fixed",
        duration_s=6.0,
    )
    files, read = index(root)
    assert read == 1 and len(files) == 7
    touched = root / "S001" / "S001-fixed.mcap"
    stat = touched.stat()
    os.utime(touched, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    assert index(root)[1] == 1
    (root / "S002" / "S002-fixed.mcap").unlink()
    files, read = index(root)
    assert read == 0 and len(files) == 6
    assert "S002-fixed" not in set(files["session"])


def test_quality_flags_name_what_is_wrong(tmp_path: Path) -> None:
    write_study_session(
        tmp_path / "drops.mcap", subject="S001", law="fixed", scale=1.0, session_id="drops", drops=3
    )
    write_study_session(
        tmp_path / "open.mcap",
        subject="S002",
        law="fixed",
        scale=1.0,
        session_id="open",
        finished=False,
    )
    whole = write_study_session(
        tmp_path / "cut.mcap", subject="S003", law="fixed", scale=1.0, session_id="cut"
    )
    data = whole.read_bytes()
    whole.write_bytes(data[: len(data) // 2])  # truncated: summary and footer gone
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file at all")
    catalogue = sessions(index(tmp_path)[0]).set_index("session")
    assert catalogue.loc["drops", "flags"] == "dropped"
    assert catalogue.loc["drops", "dropped"] == 3
    assert catalogue.loc["open", "flags"] == "unfinished"
    assert set(catalogue.loc["cut", "flags"].split(",")) >= {"incomplete", "unfinished"}
    assert catalogue.loc["junk.mcap", "flags"] == "unreadable"
    files = index(tmp_path)[0].set_index("path")
    assert (
        files.loc["junk.mcap", "problem"].startswith("junk.mcap")
        or files.loc["junk.mcap", "problem"]
    )


def test_ended_early_flags_a_session_stopped_or_faulted_not_one_that_ran_its_course(
    tmp_path: Path,
) -> None:
    ends = {
        "older": "",  # an older hilrig's: ran its course
        "reached": "duration reached",
        "sigint": "interrupted by the operator (SIGINT)",
        "sigterm": "terminated (SIGTERM)",
        "disk": "the disk is full (/data)",
        "robot": "robot: the controller reports protective stop (safety mode 5)",
    }
    for n, (name, ended_by) in enumerate(ends.items()):
        write_study_session(
            tmp_path / f"{name}.mcap",
            subject=f"S00{n + 1}",
            law="fixed",
            scale=1.0,
            session_id=name,
            ended_by=ended_by,
        )
    catalogue = sessions(index(tmp_path)[0]).set_index("session")
    flagged = {name for name in ends if catalogue.loc[name, "flags"] == "ended-early"}
    assert flagged == {"sigint", "sigterm", "disk", "robot"}
    assert (catalogue.loc[["older", "reached"], "flags"] == "").all()


def test_a_split_session_is_one_row(tmp_path: Path) -> None:
    write_session(tmp_path / "long.mcap", subject_id="S001", session_id="long", split_s=3.0)
    files = index(tmp_path)[0]
    catalogue = sessions(files)
    assert len(files) > 1 and len(catalogue) == 1
    (row,) = catalogue.itertuples(index=False)
    assert row.parts == len(files) and row.path == "long_000.mcap"
    assert row.duration_s == pytest.approx(8.0, abs=0.01)


def test_conditions_carry_parameters_only_where_a_controller_had_several(tmp_path: Path) -> None:
    frame = pd.DataFrame(
        {
            "controller": ["adaptive", "adaptive", "fixed"],
            "params": ['{"b0": 1}', '{"b0": 2}', '{"k": 3}'],
        }
    )
    assert conditions(frame) == ['adaptive {"b0": 1}', 'adaptive {"b0": 2}', "fixed"]


def test_settings_become_columns_for_where(study: Path) -> None:
    frame = settings_columns(sessions(index(study)[0]))
    chosen = frame.query("scale > 1.2 and controller == 'fixed'")
    assert sorted(chosen["subject"]) == ["S002", "S003"]


def test_hidden_folders_and_a_missing_folder(tmp_path: Path) -> None:
    (tmp_path / ".cache").mkdir()
    (tmp_path / ".cache" / "x.mcap").write_bytes(b"")
    (tmp_path / "a.txt").write_text("not a recording")
    assert recordings(tmp_path) == []
    with pytest.raises(StudyError, match=r"^.*nowhere: not a folder of recordings$"):
        recordings(tmp_path / "nowhere")
