"""``hilrig rig serve``: bad options are one line before the rig opens; a path is printed as it
is, never read as markup."""

import signal
import subprocess
import sys
from pathlib import Path

import pytest

HILRIG = Path(sys.executable).with_name("hilrig")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rate", "0"], "--rate 0: must be within 1..10000 Hz"),
        (["--rate", "nan"], "--rate nan: must be within 1..10000 Hz"),
        (["--port-path", "gone/ft"], "--port-path gone/ft: folder gone does not exist"),
        (["--port-path", "afile/ft"], "--port-path afile/ft: afile is not a folder"),
    ],
)
def test_a_bad_option_is_one_line_before_the_rig_opens(
    tmp_path: Path, args: list[str], message: str
) -> None:
    (tmp_path / "afile").write_bytes(b"")
    result = subprocess.run(
        [str(HILRIG), "rig", "serve", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == f"error: {message}\n"
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]


def test_the_port_path_is_printed_as_given(tmp_path: Path) -> None:
    port = tmp_path / "ft[red]1"
    server = subprocess.Popen(
        [str(HILRIG), "rig", "serve", "--port-path", str(port)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stdout is not None
        lines = [server.stdout.readline() for _ in range(2)]
        server.send_signal(signal.SIGINT)
        server.communicate(timeout=30)
    finally:
        server.kill()
    assert lines[1].strip() == f"wrist F/T sensor (Kunwei, 460800 8N1): {port}"
