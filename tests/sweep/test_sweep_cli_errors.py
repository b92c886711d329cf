"""What ``hilrig sweep`` refuses, each in one line, before any work (nothing written)."""

from __future__ import annotations

import socket
import sys
from pathlib import Path

import pytest
from sweep_helpers import force_table

from hilrig.cli import run


def _refused(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    status = run(["sweep", *args])
    captured = capsys.readouterr()
    assert status == 2, captured
    assert captured.out == ""
    return captured.err


@pytest.fixture
def table(tmp_path: Path) -> Path:
    return force_table(tmp_path / "f.parquet", 3.0)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["-c", "pid"],
            "error: --controller pid: law 'pid' is not one of: fixed, variable-stiffness, "
            "adaptive\n",
        ),
        (
            ["--sweep", "adaptive.a1=1:2"],
            "error: --sweep adaptive.a1=1:2: expected START:STOP:COUNT\n",
        ),
        (["--sweep", "adaptive.a1"], "error: --sweep adaptive.a1: expected NAME.PARAM=VALUE\n"),
        (["--address", "127.0.0.1:6379"], "error: --address: only with --engine ray\n"),
    ],
)
def test_bad_specs_and_options(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    table: Path,
    options: list[str],
    message: str,
) -> None:
    assert _refused(capsys, str(table), "-o", str(tmp_path / "out"), *options) == message
    assert not (tmp_path / "out").exists()


def test_bad_sources(capsys: pytest.CaptureFixture[str], tmp_path: Path, table: Path) -> None:
    out = str(tmp_path / "out")
    assert _refused(capsys, str(tmp_path / "none"), "-o", out) == (
        f"error: {tmp_path / 'none'}: no such file or folder\n"
    )
    assert _refused(capsys, str(table), "--closed-loop", "-o", out) == (
        f"error: {table}: --closed-loop needs a recorded session (.mcap): the contact is fitted "
        "from the recorded force and the robot's measured motion\n"
    )
    (tmp_path / "empty").mkdir()
    assert _refused(capsys, str(tmp_path / "empty"), "-o", out) == (
        f"error: nothing to sweep in {tmp_path / 'empty'}: no .mcap sessions\n"
    )
    assert not (tmp_path / "out").exists()


def test_ray_not_installed(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path, table: Path
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` meets without the extra
    assert _refused(capsys, str(table), "-o", str(tmp_path / "out"), "--engine", "ray") == (
        "error: --engine ray needs Ray, which is not installed: pip install 'hilrig[ray]'\n"
    )


def test_an_address_where_no_cluster_answers(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, table: Path
) -> None:
    with socket.socket() as s:  # a port nobody listens on (bound, never listening)
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        err = _refused(
            capsys,
            str(table),
            "-o",
            str(tmp_path / "out"),
            "--engine",
            "ray",
            "--address",
            f"127.0.0.1:{port}",
        )
    assert err == (
        f"error: --address 127.0.0.1:{port}: no Ray cluster answers there (Connection refused); "
        "start one with `ray start --head`, or check the address\n"
    )
    assert _refused(
        capsys, str(table), "-o", str(tmp_path / "out"), "--engine", "ray", "--address", "head"
    ) == ("error: --address head: expected HOST:PORT of a Ray head (e.g. 10.0.0.5:6379)\n")
    assert not (tmp_path / "out").exists()


def test_the_engine_option_names_the_library_engines() -> None:
    from hilrig.cli.sweep import EngineOption
    from hilrig.sweep import ENGINES

    assert tuple(e.value for e in EngineOption) == ENGINES
