"""``hilrig view``: to a file, to a real Rerun server over gRPC, as a web viewer on localhost,
and its one-line errors."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "viz"))
from rrd_helpers import Rrd
from servers import impostor

from hilrig.viz.save_server import rerun_save_server
from hilrig.viz.sinks import rerun_binary

HILRIG = Path(sys.executable).with_name("hilrig")
RERUN = rerun_binary()
EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"


def hilrig(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(HILRIG), *args], capture_output=True, text=True, timeout=timeout)


def free_port() -> int:
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def wait_for(predicate: object, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return
        time.sleep(0.1)
    raise AssertionError("timed out")


def listening(port: int) -> bool:
    with contextlib.closing(socket.socket()) as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_save_writes_the_session_and_its_replays(tmp_path: Path) -> None:
    out = tmp_path / "view.rrd"
    result = hilrig("view", str(EXAMPLE), "-c", "fixed", "-c", "adaptive", "--save", str(out))
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        f"{EXAMPLE}: 3 run(s)",
        "  ■ recorded (adaptive)",
        "  ■ fixed (fixed)",
        "  ■ adaptive (adaptive)",
        f"wrote {out}",
    ]
    entities = Rrd(out).entities()
    assert {
        "/series/offset/x/recorded",
        "/series/offset/x/fixed",
        "/series/offset/x/adaptive",
    } <= entities


def test_file_names_are_shown_as_they_are(tmp_path: Path) -> None:
    session, out = tmp_path / "a[red]b.mcap", tmp_path / "c[bold]d.rrd"
    session.write_bytes(EXAMPLE.read_bytes())
    result = hilrig("view", str(session), "--save", str(out))
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        f"{session}: 1 run(s)",
        "  ■ recorded (adaptive)",
        f"wrote {out}",
    ]


def test_long_sessions_say_they_are_decimated(tmp_path: Path) -> None:
    out = tmp_path / "view.rrd"
    result = hilrig("view", str(EXAMPLE), "--max-points", "1000", "--save", str(out))
    assert result.returncode == 0, result.stderr
    assert (
        "display decimated: at most 1000 of 3499 samples per series (min/max per bucket); "
        "the file is untouched"
    ) in result.stdout
    _, values = Rrd(out).scalars("/series/offset/x/recorded")
    assert len(values) <= 1000


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # what `rerun --save` writes
def test_connect_streams_to_a_running_rerun_server(tmp_path: Path) -> None:
    out = tmp_path / "received.rrd"
    with rerun_save_server(out) as url:
        result = hilrig("view", str(EXAMPLE), "-c", "fixed", "--connect", url)
        assert result.returncode == 0, result.stderr
    rrd = Rrd(out)
    _, values = rrd.scalars("/series/offset/x/fixed")
    assert len(values) == 3499
    assert any(v.kind == "3D" for v in rrd.views())


def test_a_ctrl_c_right_after_the_web_viewer_line_ends_the_wait_and_nothing_else() -> None:
    """The line is printed once Ctrl-C is caught: a Ctrl-C at once (a test that reads the line
    and signals, on a loaded machine) ends the wait cleanly instead of interrupting the command
    (exit 130, as CI saw)."""
    from hilrig.cli.view import _wait_for_interrupt

    announced = []

    def announce() -> None:
        announced.append(True)
        os.kill(os.getpid(), signal.SIGINT)  # delivered before announce returns

    _wait_for_interrupt(announce)  # returns: no KeyboardInterrupt
    assert announced == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back


def test_web_serves_the_viewer_on_localhost_until_interrupted() -> None:
    port, web_port = free_port(), free_port()
    view = subprocess.Popen(
        [
            str(HILRIG),
            "view",
            str(EXAMPLE),
            "--web",
            "--port",
            str(port),
            "--web-port",
            str(web_port),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert view.stdout is not None
        line = ""
        deadline = time.monotonic() + 60
        while not line.startswith("web viewer:") and time.monotonic() < deadline:
            line = view.stdout.readline()
        assert line.strip() == (
            f"web viewer: http://127.0.0.1:{web_port}/?url=rerun+http://127.0.0.1:{port}/proxy"
            "  (Ctrl-C to stop)"
        )
        with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=10) as page:
            assert page.status == 200
            assert b"<html" in page.read().lower()
        listeners = Path("/proc/net/tcp").read_text()
        assert f"0100007F:{web_port:04X}" in listeners  # bound to 127.0.0.1, not every interface
        assert f"00000000:{web_port:04X}" not in listeners
    finally:
        view.send_signal(signal.SIGINT)
        assert view.wait(30) == 0
    wait_for(lambda: not listening(web_port))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--save", "x.txt"], "--save x.txt: the name must end in .rrd"),
        (
            ["--save", "/no/such/dir/x.rrd"],
            "--save /no/such/dir/x.rrd: directory /no/such/dir does not exist",
        ),
        (["--save", "x.rrd", "--web"], "--save and --web: choose one destination"),
        (
            ["--connect", "http://x"],
            "--connect 'http://x': expected rerun+http://HOST:PORT/proxy (or rerun://, rerun+https://)",
        ),
        (
            ["--web", "--port", "9000", "--web-port", "9000"],
            "--port and --web-port are both 9000: they must differ",
        ),
        (["--set", "fixed.kd=5", "--save", "x.rrd"], "--set changes a --controller: name one"),
        (["--overwrite"], "--overwrite replaces a --save file: name one"),
        (["-c", "wobbly", "--save", "x.rrd"], None),
    ],
)
def test_bad_options_are_one_line_errors(
    tmp_path: Path, args: list[str], message: str | None
) -> None:
    result = subprocess.run(
        [str(HILRIG), "view", str(EXAMPLE), *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert result.returncode == 2
    assert result.stdout == ""
    assert len(result.stderr.splitlines()) == 1
    if message is not None:
        assert result.stderr == f"error: {message}\n"
    else:
        assert "wobbly" in result.stderr
    assert not list(tmp_path.iterdir())  # nothing written


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    result = hilrig("view", str(tmp_path / "gone.mcap"), "--save", str(tmp_path / "x.rrd"))
    assert result.returncode == 2
    assert result.stderr.startswith(f"error: {tmp_path / 'gone.mcap'}")
    assert len(result.stderr.splitlines()) == 1


def test_a_truncated_session_is_viewed_with_a_warning(tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    data = EXAMPLE.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    result = hilrig("view", str(cut), "--save", str(tmp_path / "cut.rrd"))
    assert result.returncode == 0, result.stderr
    lines = result.stderr.splitlines()
    assert lines and all(line.startswith(f"warning: {cut}") for line in lines)


def test_without_a_display_the_desktop_viewer_fails_in_one_line(tmp_path: Path) -> None:
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")
    }
    result = subprocess.run(
        [str(HILRIG), "view", str(EXAMPLE), "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert result.returncode == 2
    assert result.stderr == (
        "error: no display for the Rerun viewer (DISPLAY and WAYLAND_DISPLAY are not set): save "
        "to a file or use the web viewer or a viewer's URL\n"
    )


def test_connect_where_nothing_listens_fails_at_once_in_one_line() -> None:
    url = f"rerun+http://127.0.0.1:{free_port()}/proxy"  # bound and released: nobody listens
    result = hilrig("view", str(EXAMPLE), "--connect", url, timeout=60)  # Rerun would retry
    assert result.returncode == 2
    assert result.stdout == ""
    assert (
        result.stderr == f"error: --connect {url}: no viewer listening there (Connection refused)\n"
    )


@pytest.mark.parametrize(
    ("answer", "why"),
    [(None, "no answer within 3 s"), (b"\x00\x15\xfe garbage\r\n", "its answer is not HTTP")],
)
def test_connect_where_something_else_listens_fails_in_one_line(
    answer: bytes | None, why: str
) -> None:
    """A loopback server that accepts and stays silent, or answers garbage: Rerun would wait on
    it for minutes."""
    with impostor(answer) as url:
        result = hilrig("view", str(EXAMPLE), "--connect", url, timeout=60)
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == (
        f"error: --connect {url}: nothing answering like a Rerun viewer there ({why})\n"
    )


def test_save_refuses_an_existing_file_and_overwrite_replaces_it(tmp_path: Path) -> None:
    out = tmp_path / "kept.rrd"
    out.write_bytes(b"a view someone keeps")
    result = hilrig("view", str(EXAMPLE), "--save", str(out))
    assert (result.returncode, result.stdout) == (2, "")
    assert result.stderr == f"error: {out}: already exists; pass --overwrite to replace it\n"
    assert out.read_bytes() == b"a view someone keeps"
    assert [p.name for p in tmp_path.iterdir()] == ["kept.rrd"]
    result = hilrig("view", str(EXAMPLE), "--save", str(out), "--overwrite")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-1] == f"wrote {out}"
    assert "/series/offset/x/recorded" in Rrd(out).entities()
    assert [p.name for p in tmp_path.iterdir()] == ["kept.rrd"]  # no temporary left
