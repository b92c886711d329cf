"""The recorder's start in two steps and its health: rows committed before ``begin`` wait in the
rings and are all written; a recorder stopped before ``begin`` writes no file; a killed one is
seen dead by ``alive()`` and its ``stop()`` says how it ended."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from test_recorder import ROW_TOPICS, check_rows, push_rows, session

from hilrig.errors import RecordingError
from hilrig.recording import load
from hilrig.rig import RecorderFeed, RecorderProcess
from hilrig.rig.recorder_child import RECORDER_NICENESS


def test_rows_committed_before_begin_are_all_written(tmp_path: Path) -> None:
    path = tmp_path / "early.mcap"
    n_before, n = 1500, 2500
    with RecorderFeed(rows=2048) as feed:
        recorder = RecorderProcess(path, feed=feed)
        recorder.spawn()
        assert recorder.pid is not None
        push_rows(feed, 0, n_before, paced=False)
        assert not path.exists()  # no file before begin
        assert (feed.ft.backlog, feed.joint.backlog, feed.tick.backlog) == (n_before,) * 3
        recorder.begin(session(), {"bias_in_sensor": [0.0] * 6})
        assert recorder.ready(60.0)
        push_rows(feed, n_before, n)
        assert recorder.stop() == (7 * n, 0)
    frames = load(path)
    assert {t: len(frames[t]) for t in ROW_TOPICS} == dict.fromkeys(ROW_TOPICS, n)
    check_rows(frames, n)


def test_the_recorder_runs_ahead_of_other_work_where_permitted(tmp_path: Path) -> None:
    with RecorderFeed(rows=64) as feed:
        recorder = RecorderProcess(tmp_path / "nice.mcap", feed=feed)
        recorder.spawn()
        recorder.begin(session(), {"bias_in_sensor": [0.0] * 6})
        assert recorder.ready(60.0) and recorder.pid is not None
        niceness = os.getpriority(os.PRIO_PROCESS, recorder.pid)
        assert recorder.stop() == (0, 0)
    permitted = os.geteuid() == 0  # or CAP_SYS_NICE, which a test run as a user does not have
    assert niceness == (RECORDER_NICENESS if permitted else os.getpriority(os.PRIO_PROCESS, 0))


def test_a_recorder_stopped_before_begin_writes_no_file(tmp_path: Path) -> None:
    path = tmp_path / "never.mcap"
    with RecorderFeed(rows=64) as feed:
        recorder = RecorderProcess(path, feed=feed)
        recorder.spawn()
        push_rows(feed, 0, 10, paced=False)
        assert recorder.stop() == (0, 0)
        assert not recorder.alive()
    assert not path.exists()


def test_a_killed_recorder_is_seen_dead_and_stop_says_how_it_ended(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    with RecorderFeed(rows=64) as feed:
        recorder = RecorderProcess(path, feed=feed)
        assert not recorder.alive()  # not spawned yet
        recorder.start(session())
        assert recorder.alive()
        assert recorder.pid is not None
        os.kill(recorder.pid, signal.SIGKILL)
        deadline = time.monotonic() + 20
        while recorder.alive():
            assert time.monotonic() < deadline, "the killed recorder never ended"
            time.sleep(0.01)
        with pytest.raises(RecordingError, match="exited with code -9 before reporting done"):
            recorder.stop()


def test_begin_twice_and_ready_before_spawn_are_refused(tmp_path: Path) -> None:
    with RecorderFeed(rows=64) as feed:
        recorder = RecorderProcess(tmp_path / "twice.mcap", feed=feed)
        with pytest.raises(RecordingError, match="not started"):
            recorder.ready()
        recorder.start(session())
        with pytest.raises(RecordingError, match="already begun"):
            recorder.begin(session(), None)
        assert recorder.stop() == (0, 0)
