"""One session at a time on a machine: a real flock, held by threads and by another process."""

import subprocess
import sys
import threading
from pathlib import Path

import pytest

from hilrig.errors import HilrigError
from hilrig.recording import inspect
from hilrig.rig import SessionConfig, record_session
from hilrig.rig.machine_lock import WAITING, one_session_at_a_time

WAIT_S = 900  # bounds for the waits below (a loaded machine, other sessions), never reached
HOLD = """
import sys, threading
from pathlib import Path
from hilrig.rig.machine_lock import one_session_at_a_time
with one_session_at_a_time(threading.Event(), path=Path(sys.argv[1])):
    print("held", flush=True)
    sys.stdin.read()
"""


def test_a_second_holder_says_so_once_waits_and_goes_on_when_the_first_is_done(
    tmp_path: Path,
) -> None:
    path = tmp_path / "session.lock"
    said: list[str] = []
    waiting, entered = threading.Event(), threading.Event()

    def second() -> None:
        def on_wait(text: str) -> None:
            said.append(text)
            waiting.set()

        with one_session_at_a_time(threading.Event(), on_wait, path=path):
            entered.set()

    with one_session_at_a_time(threading.Event(), path=path):
        thread = threading.Thread(target=second)
        thread.start()
        assert waiting.wait(WAIT_S)
        assert not entered.is_set()
    thread.join(WAIT_S)
    assert entered.is_set() and said == [WAITING]


def test_stop_while_waiting_gives_up_with_one_line(tmp_path: Path) -> None:
    path = tmp_path / "session.lock"
    stop = threading.Event()
    stop.set()
    with (
        one_session_at_a_time(threading.Event(), path=path),
        pytest.raises(HilrigError) as raised,
        one_session_at_a_time(stop, path=path),
    ):
        pytest.fail("entered while the lock was held")
    assert str(raised.value) == "stopped while waiting for the other session: nothing recorded"
    with one_session_at_a_time(stop, path=path):  # free again: a set stop does not matter
        pass


def test_a_killed_holder_leaves_no_stale_lock(tmp_path: Path) -> None:
    path = tmp_path / "session.lock"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        stop = threading.Event()
        stop.set()
        with (
            pytest.raises(HilrigError, match="stopped while waiting"),
            one_session_at_a_time(stop, path=path),
        ):
            pass
    finally:
        holder.kill()
        holder.wait(WAIT_S)
    with one_session_at_a_time(stop, path=path):
        pass


def test_a_lock_file_that_cannot_be_opened_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "missing" / "session.lock"
    with pytest.raises(HilrigError) as raised, one_session_at_a_time(threading.Event(), path=path):
        pass
    assert str(raised.value) == (f"session lock {path}: cannot open it (No such file or directory)")


def test_a_session_waits_for_the_machine_s_other_session_before_it_starts(
    tmp_path: Path,
) -> None:
    out = tmp_path / "s.mcap"
    said: list[str] = []
    waiting = threading.Event()
    results = []

    def on_wait(text: str) -> None:
        said.append(text)
        waiting.set()

    def session() -> None:
        config = SessionConfig(out=out, subject_id="S001", duration_s=1.0)
        results.append(record_session(config, stop=threading.Event(), on_wait=on_wait))

    with one_session_at_a_time(threading.Event()):  # as another session on the machine
        thread = threading.Thread(target=session)
        thread.start()
        assert waiting.wait(WAIT_S)
        assert list(tmp_path.iterdir()) == []  # nothing started: no file, no folder
    thread.join(WAIT_S)
    assert said == [WAITING] and len(results) == 1
    assert inspect(out).complete
