"""The spawn helper: a child ignores SIGINT, reports over its Pipe, answers requests (as the
emulated rig does), and a failed or silent child is named in one line."""

from __future__ import annotations

import os
import signal
import time
from multiprocessing.connection import Connection

import pytest

from hilrig.errors import HilrigError, LinkError
from hilrig.rig import ChildProcess
from hilrig.rig.child import report


def serve(conn: Connection, greeting: str) -> None:
    """Report ready, answer each request with its double until "stop"."""
    report(conn, "ready", greeting)
    while (message := conn.recv()) != "stop":
        report(conn, "ok", 2 * message)
    report(conn, "done", "bye")


def fail(conn: Connection) -> None:
    report(conn, "error", "cannot open the device")


def silent(conn: Connection) -> None:
    conn.recv()


def test_a_child_reports_answers_requests_ignores_sigint_and_stops_on_request() -> None:
    child = ChildProcess("hilrig-test-child", "test child", LinkError)
    child.start(serve, ("hello",))
    assert child.wait_report("ready", 60) == "hello"
    assert child.pid is not None
    os.kill(child.pid, signal.SIGINT)  # the parent's business: ignored
    for k in range(3):
        child.send(k)
        assert child.receive("ok") == 2 * k
    assert child.stop(20, message="stop")
    assert child.receive("done") == "bye"
    assert (child.alive(), child.exitcode) == (False, 0)
    child.close()


def test_an_error_report_and_a_killed_child_raise_one_line() -> None:
    child = ChildProcess("hilrig-test-child", "test child", LinkError)
    child.start(fail)
    with pytest.raises(LinkError, match=r"^test child: cannot open the device$"):
        child.wait_report("ready", 60)
    silent_child = ChildProcess("hilrig-test-child", "silent child")
    silent_child.start(silent)
    assert silent_child.pid is not None
    os.kill(silent_child.pid, signal.SIGKILL)
    deadline = time.monotonic() + 20
    while silent_child.alive():
        assert time.monotonic() < deadline, "the killed child never ended"
        time.sleep(0.01)
    with pytest.raises(HilrigError, match=r"^silent child: exited with code -9 before reporting"):
        silent_child.receive("ready")
    silent_child.close()
    child.close()


def test_a_child_that_does_not_end_is_killed() -> None:
    child = ChildProcess("hilrig-test-child", "stuck child")
    child.start(serve, ("hi",))
    assert child.wait_report("ready", 60) == "hi"
    assert not child.stop(0.0)  # not asked to stop: killed
    assert child.exitcode == -signal.SIGKILL
    child.close()
