"""Files that claim one session id (a copy, or ids of a second's resolution from before ids
were ULIDs) are sessions of their own, each flagged, in the catalogue, `study`'s commands and
the report; a split session's parts stay one session."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from study_helpers import write_study, write_study_session

from hilrig.cli import run
from hilrig.study.catalogue import FLAGS, index, session_files, sessions

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from analysis_helpers import write_session

OLD_ID = "20261207-165147"  # two `hilrig record` started in one second used to share this


TWINS = (f"S004/{OLD_ID}.mcap", f"S005/{OLD_ID}.mcap")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two subjects' sessions under one old-style id (:data:`TWINS`), beside a study of three
    subjects."""
    root = tmp_path_factory.mktemp("twins")
    write_study(root, ("S001", "S002", "S003"), ("adaptive", "fixed"), duration_s=7.0)
    for name, scale in zip(TWINS, (1.5, 2.0), strict=True):
        subject = name.split("/")[0]
        write_study_session(
            root / name, subject=subject, law="adaptive", scale=scale, session_id=OLD_ID
        )
    return root


@pytest.fixture
def study(recorded: Path, tmp_path: Path) -> Path:
    root = tmp_path / "study"
    shutil.copytree(recorded, root, ignore=shutil.ignore_patterns(".hilrig-study"))
    return root


def _subject(path: Path) -> str:
    """The file's subject, as the official mcap reader reads its session record."""
    with path.open("rb") as f:
        records = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    return records["session"]["subject_id"]


def _ok(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    status = run(list(args))
    out, err = capsys.readouterr()
    assert status == 0, err
    return out


def test_two_files_claiming_one_id_are_two_sessions_each_flagged(study: Path) -> None:
    catalogue = sessions(index(study)[0]).set_index("path")
    assert len(catalogue) == 8
    for name in TWINS:
        row = catalogue.loc[name]
        assert row["session"] == f"{OLD_ID}@{name}"
        assert row["subject"] == _subject(study / name) and row["parts"] == 1
        assert row["flags"] == "duplicate-id"
    others = catalogue.drop(index=list(TWINS))
    assert (others["flags"] == "").all() and not others["session"].str.contains("@").any()
    assert set(catalogue["session"]).isdisjoint({OLD_ID})
    assert "duplicate-id" in FLAGS


def test_a_copied_split_session_is_two_sessions_of_all_their_parts(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    write_session(tmp_path / "a" / "long.mcap", subject_id="S001", session_id="long", split_s=3.0)
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    files = index(tmp_path)[0]
    catalogue = sessions(files)
    parts = len(files) // 2
    assert parts > 1 and list(catalogue["path"]) == ["a/long_000.mcap", "b/long_000.mcap"]
    assert list(catalogue["session"]) == ["long@a/long_000.mcap", "long@b/long_000.mcap"]
    assert list(catalogue["parts"]) == [parts, parts]
    assert list(catalogue["flags"]) == ["duplicate-id,unfinished"] * 2  # no outcome record
    assert session_files(files)["long@b/long_000.mcap"] == [
        f"b/long_{n:03d}.mcap" for n in range(parts)
    ]


def test_study_commands_list_both_and_name_them_to_exclude_one(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second = (f"{OLD_ID}@{name}" for name in TWINS)
    indexed = _ok(capsys, "study", "index", str(study))
    assert indexed.startswith("8 sessions in 8 files: 8 read")
    assert f"flagged {first}: duplicate-id" in indexed
    assert f"flagged {second}: duplicate-id" in indexed
    listed = _ok(
        capsys, "study", "list", str(study), "--where", "flags != ''", "--columns", "session"
    )
    assert "2 of 8 sessions" in listed and first in listed and second in listed
    assert run(["study", "exclude", str(study), OLD_ID, "--reason", "r"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == (
        f"error: {OLD_ID!r} is claimed by 2 sessions of {study}: name one as {first} or {second}\n"
    )
    excluded = _ok(capsys, "study", "exclude", str(study), second, "--reason", "copy")
    assert excluded.startswith(f"excluded {second}: copy")


def test_the_report_counts_both_and_notes_the_flag(
    study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "report.html"
    printed = _ok(capsys, "report", str(study), "-o", str(out), "--resamples", "999")
    assert printed.startswith(f"wrote {out}: 8 sessions of 5 subjects, 0 excluded")
    html = out.read_text(encoding="utf-8")
    for name in TWINS:
        key = f"{OLD_ID}@{name}"
        assert f"<code>{key}</code>" in html
        assert f"kept in the study though flagged: {key} (duplicate-id)" in html
