"""One way to fail: expected failures and command-line mistakes are one line and exit 2, a bug is
one line asking for a report (exit 3; ``--debug`` shows the traceback), Ctrl-C exits 130, and
a warning is one clean line."""

import os
import subprocess
import sys
import tomllib
import warnings
from pathlib import Path

import pytest

import hilrig.paper.reproduce
from hilrig.cli import run
from hilrig.recording import RecordingWarning

HILRIG = Path(sys.executable).with_name("hilrig")


def test_an_expected_error_is_one_line_at_any_terminal_width() -> None:
    result = subprocess.run(
        [str(HILRIG), "rig", "serve", "--scenario", "[bold]shove"],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "40"},
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stdout == ""
    assert result.stderr == (
        "error: unknown scenario '[bold]shove'; known: hand-contact, none, paper-body, "
        "paper-end-effector\n"
    )


def test_version_is_the_projects() -> None:
    result = subprocess.run([str(HILRIG), "--version"], capture_output=True, text=True, timeout=60)
    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]
    assert (result.returncode, result.stdout) == (0, f"hilrig {project['version']}\n")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["record", "--subject", "S001", "--controller", "pid"],
            "error: Invalid value for '--controller': 'pid' is not one of 'fixed', "
            "'variable-stiffness', 'adaptive'. (see hilrig record --help)\n",
        ),
        (
            ["record", "--subject", "S001", "--rate", "fast"],
            "error: Invalid value for '--rate': Input should be a valid number, unable to parse "
            "string as a number (see hilrig record --help)\n",
        ),
        (["record"], "error: Missing option '--subject'. (see hilrig record --help)\n"),
        (["recrd"], "error: No such command 'recrd'. Did you mean 'record', 'recover'? "),
    ],
)
def test_a_command_line_mistake_is_one_line_with_status_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(args) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith(message) and err.count("\n") == 1


def boom(*args: object, **kwargs: object) -> None:
    raise RuntimeError("boom\nin two lines")


def test_a_bug_is_one_line_asking_for_a_report_with_status_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(hilrig.paper.reproduce, "reproduce", boom)
    assert run(["paper", "--out", str(tmp_path / "paper")]) == 3
    out, err = capsys.readouterr()
    assert out == ""
    assert err == (
        "error: unexpected RuntimeError: boom in two lines. This is a bug in hilrig: please "
        "report it; run again with hilrig --debug ... for the full traceback\n"
    )


def test_debug_shows_the_full_traceback_before_the_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(hilrig.paper.reproduce, "reproduce", boom)
    assert run(["--debug", "paper", "--out", str(tmp_path / "paper")]) == 3
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):\n")
    assert "RuntimeError: boom\nin two lines\n" in err
    assert err.endswith(
        "error: unexpected RuntimeError: boom in two lines. This is a bug in hilrig: please "
        "report it with the traceback above\n"
    )
    # the option holds for one command line only
    assert run(["paper", "--out", str(tmp_path / "paper")]) == 3
    assert "Traceback" not in capsys.readouterr().err


def test_ctrl_c_outside_a_session_is_one_line_with_status_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(hilrig.paper.reproduce, "reproduce", interrupted)
    assert run(["paper", "--out", str(tmp_path / "paper")]) == 130
    assert capsys.readouterr().err == "interrupted: stopped by Ctrl-C\n"


def test_a_warning_is_one_clean_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def warn(*args: object, **kwargs: object) -> None:
        warnings.warn("cut.mcap: unfinished recording\n(no summary)", RecordingWarning, 2)
        raise KeyboardInterrupt  # ends the command before any work

    monkeypatch.setattr(hilrig.paper.reproduce, "reproduce", warn)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        run(["paper", "--out", str(tmp_path / "paper")])
    err = capsys.readouterr().err
    assert err.splitlines()[0] == "warning: cut.mcap: unfinished recording (no summary)"
