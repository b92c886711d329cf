"""Ctrl-C as a terminal sends it (SIGINT to the command's whole process group) ends every
long-running command on the first one: the command exits 130 with one ``interrupted:`` line
(a server that runs until Ctrl-C exits 0, silent), and no process it started outlives it.

Each command runs in a session of its own and is interrupted right after it starts, while it
works, or once it says it is ready. The bound on its end is a hang's, not a timing requirement
(the measured time is in each failure's message)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import psutil
import pytest

HILRIG = Path(sys.executable).with_name("hilrig")
EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
#: A hang's bound: a command still running this long after Ctrl-C ignored it.
ENDED_S = 10.0
#: How long a process the command started may take to follow it (its parent-death signal).
FOLLOW_S = 10.0
READY_S = 120.0


@dataclass
class Ended:
    status: int
    seconds: float
    stdout: str
    stderr: str
    left: list[str]  # processes it started that outlived it

    def lines(self) -> list[str]:
        """stderr's lines, less the ``waiting:`` line of a session that waited for another."""
        return [line for line in self.stderr.splitlines() if not line.startswith("waiting: ")]


def free_port() -> int:
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def interrupt(
    args: list[str], cwd: Path, *, ready: str | None = None, after_s: float = 0.0
) -> Ended:
    """Run ``hilrig ARGS`` in a session of its own; once stdout holds ``ready`` (if given) and
    ``after_s`` more seconds passed, Ctrl-C its process group; how it ended."""
    out, err = cwd / "stdout.txt", cwd / "stderr.txt"
    with out.open("w") as stdout, err.open("w") as stderr:
        process = subprocess.Popen(
            [str(HILRIG), *args], stdout=stdout, stderr=stderr, cwd=cwd, start_new_session=True
        )
    try:
        deadline = time.monotonic() + READY_S
        while ready is not None and ready not in out.read_text():
            assert process.poll() is None, err.read_text()
            assert time.monotonic() < deadline, f"never said {ready!r}: {err.read_text()}"
            time.sleep(0.05)
        time.sleep(after_s)
        started = psutil.Process(process.pid).children(recursive=True)
        os.killpg(process.pid, signal.SIGINT)
        start = time.monotonic()
        try:
            status = process.wait(ENDED_S)
        except subprocess.TimeoutExpired:
            status = -999  # hung: killed below
        seconds = time.monotonic() - start
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    _, alive = psutil.wait_procs(started, timeout=FOLLOW_S)
    left = [" ".join(p.cmdline()[:3]) for p in alive if _running(p)]
    for p in alive:
        with contextlib.suppress(psutil.Error):
            p.kill()
    return Ended(status, seconds, out.read_text(), err.read_text(), left)


def _running(process: psutil.Process) -> bool:
    try:
        return process.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def assert_interrupted(ended: Ended) -> None:
    """Exit 130 and one ``interrupted:`` line (or killed by the signal itself before Python
    could catch it, silent), within the bound, nothing left running."""
    took = f"ended {ended.seconds:.2f} s after Ctrl-C; stderr {ended.stderr!r}"
    assert ended.status in (130, -signal.SIGINT), took
    if ended.status == 130:
        assert len(ended.lines()) == 1 and ended.lines()[0].startswith("interrupted: "), took
    else:
        assert ended.stderr == "", took
    assert ended.left == [], took


@pytest.fixture
def sessions(tmp_path: Path) -> Path:
    """Six copies of the example session."""
    folder = tmp_path / "in"
    folder.mkdir()
    for n in range(6):
        shutil.copy(EXAMPLE, folder / f"S{n:03d}.mcap")
    return folder


WEB_RUNS = [("ready", 0.0)] * 3 + [("ready", 0.3), ("start", 1.0), ("start", 2.5)]


@pytest.mark.parametrize(("when", "after_s"), WEB_RUNS)
def test_view_web_ends_on_the_first_ctrl_c(tmp_path: Path, when: str, after_s: float) -> None:
    """Once it serves: exit 0, nothing on stderr (Rerun's server, which a terminal's Ctrl-C
    used to reach first, logged its lost connection there); before: an interrupt."""
    args = ["view", str(EXAMPLE), "--web", "--port", str(free_port())]
    args += ["--web-port", str(free_port())]
    ready = "web viewer: " if when == "ready" else None
    ended = interrupt(args, tmp_path, ready=ready, after_s=after_s)
    took = f"ended {ended.seconds:.2f} s after Ctrl-C; stderr {ended.stderr!r}"
    if when == "ready":
        assert (ended.status, ended.stderr, ended.left) == (0, "", []), took
    elif ended.status == 0:  # it was serving already on this machine
        assert (ended.stderr, ended.left) == ("", []), took
    else:
        assert_interrupted(ended)


def test_rig_serve_ends_on_the_first_ctrl_c(tmp_path: Path) -> None:
    args = ["rig", "serve", "--port-path", str(tmp_path / "ft")]
    ended = interrupt(args, tmp_path, ready="Ctrl-C to stop")
    took = f"ended {ended.seconds:.2f} s after Ctrl-C; stderr {ended.stderr!r}"
    assert (ended.status, ended.left) == (0, []), took
    assert [line for line in ended.stderr.splitlines() if line] == [], took


@pytest.mark.parametrize("after_s", [0.3, 3.0])
@pytest.mark.parametrize(
    "command",
    [
        ["paper", "--out", "paper"],
        ["replay", str(EXAMPLE), "--closed-loop", "-c", "fixed", "-c", "adaptive"],
        ["analyze", "{in}"],
        ["report", "{in}", "-o", "report.html"],
        [
            "sweep",
            "{in}",
            "-c",
            "adaptive",
            "--sweep",
            "adaptive.a1=5,10,20",
            "-o",
            "sw",
            "-j",
            "2",
        ],
        ["study", "simulate", "study", "--subjects", "2", "--controllers", "fixed,adaptive"],
        ["demo", "--out", "demo"],
        ["doctor", "--seconds", "10"],
    ],
    ids=lambda c: "-".join(c[:2]) if c[0] == "study" else c[0],
)
def test_a_long_command_ends_on_the_first_ctrl_c(
    tmp_path: Path, sessions: Path, command: list[str], after_s: float
) -> None:
    args = [arg.replace("{in}", str(sessions)) for arg in command]
    if args[0] == "analyze":
        args = ["analyze", *map(str, sorted(sessions.iterdir()))]
    ended = interrupt(args, tmp_path, after_s=after_s)
    if ended.status == 0 and after_s > 1:  # done before the Ctrl-C on a fast machine
        assert ended.left == [] and "interrupted" not in ended.stderr, ended.stderr
        return
    assert_interrupted(ended)


def test_a_sweep_ends_its_running_task_on_ctrl_c(tmp_path: Path) -> None:
    """A long task (seconds here) is ended, not waited for: nothing of it is written (its
    files are hidden temporaries until whole), and a rerun would redo it."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "sweep"))
    from sweep_helpers import force_table

    from hilrig.sweep import partition_files

    table = force_table(tmp_path / "long.parquet", 3000.0)
    args = ["sweep", str(table), "-c", "adaptive", "-o", "out", "-j", "1"]
    out, err = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
    with out.open("w") as stdout, err.open("w") as stderr:
        sweep = subprocess.Popen(
            [str(HILRIG), *args], stdout=stdout, stderr=stderr, cwd=tmp_path, start_new_session=True
        )
    try:
        deadline = time.monotonic() + READY_S
        while not (workers := psutil.Process(sweep.pid).children()):
            assert sweep.poll() is None and time.monotonic() < deadline, err.read_text()
            time.sleep(0.05)
        time.sleep(0.5)  # the task has started
        os.killpg(sweep.pid, signal.SIGINT)
        start = time.monotonic()
        status = sweep.wait(ENDED_S * 3)
        seconds = time.monotonic() - start
    finally:
        sweep.kill()
        sweep.wait()
    took = f"ended {seconds:.2f} s after Ctrl-C; stderr {err.read_text()!r}"
    assert status == 130 and err.read_text() == "interrupted: stopped by Ctrl-C\n", took
    assert partition_files(tmp_path / "out") == [], took
    assert psutil.wait_procs(workers, timeout=FOLLOW_S)[1] == []


def test_view_web_ends_when_its_server_dies(tmp_path: Path) -> None:
    """A Rerun server killed under it ends the wait with one line, not a wait for Ctrl-C."""
    args = [str(HILRIG), "view", str(EXAMPLE), "--web", "--port", str(free_port())]
    args += ["--web-port", str(free_port())]
    view = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert view.stdout is not None
        while not view.stdout.readline().startswith("web viewer: "):
            assert view.poll() is None
        (server,) = psutil.Process(view.pid).children()
        server.kill()
        _, stderr = view.communicate(timeout=ENDED_S)
    finally:
        view.kill()
    assert view.returncode == 2, stderr
    assert stderr.startswith("error: the Rerun web server exited with code -9")
    assert len(stderr.splitlines()) == 1, stderr


def test_a_ctrl_c_caught_in_a_destructor_is_delivered_again() -> None:
    """Python cannot raise from ``__del__``: a Ctrl-C that lands there was printed and lost,
    and the command went on (to wait, perhaps, for a Ctrl-C that had come)."""
    from hilrig.cli import _unraisable

    class Closing:
        def __del__(self) -> None:
            raise KeyboardInterrupt  # as a Ctrl-C arriving while it runs

    shown: list[object] = []
    hook, sys.unraisablehook = sys.unraisablehook, _unraisable(shown.append)
    try:
        with pytest.raises(KeyboardInterrupt):
            Closing()
            for _ in range(1000):  # the signal's handler runs between these
                time.sleep(0.001)
    finally:
        sys.unraisablehook = hook
    assert shown == []


def test_a_ctrl_c_python_wrapped_is_an_interrupt() -> None:
    """Python 3.11 wraps a Ctrl-C raised in ``__set_name__`` (a class made while a module is
    imported) in a RuntimeError: it ended a command as a bug (exit 3)."""
    from hilrig.cli.errors import interrupted_by

    class Field:
        def __set_name__(self, owner: type, name: str) -> None:
            raise KeyboardInterrupt

    with pytest.raises(BaseException) as caught:
        type("Record", (), {"field": Field()})
    assert interrupted_by(caught.value)
    assert not interrupted_by(RuntimeError("a bug"))
