"""The recorder process: every row the loop commits reaches its topic with its values (read by
hilrig and by the official mcap reader); a killed recorder's file recovers; a stalled one costs
drops, never a blocked producer; SIGINT is ignored, SIGTERM and the parent's death finish the
file."""

from __future__ import annotations

import gc
import math
import multiprocessing
import os
import signal
import time
from collections import Counter
from collections.abc import Iterator
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from hilrig.errors import RecordingError
from hilrig.recording import EventKind, EventRecord, SessionInfo, inspect, load, recover
from hilrig.rig import AXIS_NAMES, RecorderFeed, RecorderProcess

START_MONO_NS = 10_000_000_000
TICK_NS = 1_000_000
URDF = '<?xml version="1.0"?>\n<robot name="aubo_i5"><link name="base_link"/></robot>\n'
ROW_TOPICS = (
    "/ft/wrist",
    "/joint_states",
    "/controller/input",
    "/controller/state",
    "/trajectory/desired",
    "/trajectory/commanded",
    "/diagnostics/loop",
)


def session() -> SessionInfo:
    return SessionInfo(
        session_id="recorder-test",
        subject_id="S012",
        rig="emulated",
        controller="adaptive",
        start_utc_ns=1_767_225_600_000_000_000,
        start_monotonic_ns=START_MONO_NS,
    )


def t_of(i: int) -> int:
    """Row i's host time (ns): synthetic, so the test knows every value it wrote."""
    return START_MONO_NS + i * TICK_NS


def wrench_of(i: int) -> np.ndarray:
    return np.arange(6) * 0.5 + i


def axes_of(i: int, field: int) -> np.ndarray:
    return np.arange(9) * 0.01 + field * 10 + i * 1e-3


def push_rows(feed: RecorderFeed, start: int, stop: int, *, paced: bool = True) -> None:
    """Push rows ``start..stop-1`` of every ring (about 1 kHz when ``paced``)."""
    deadline = time.monotonic_ns()
    for i in range(start, stop):
        if paced:
            deadline += TICK_NS
            time.sleep(max(0, deadline - time.monotonic_ns()) / 1e9)
        fill_rows(feed, i)


def fill_rows(feed: RecorderFeed, i: int) -> None:
    ft = feed.ft_slot()
    if ft is not None:
        ft["t_ns"], ft["seq"], ft["wrench"] = t_of(i), i, wrench_of(i)
    feed.commit_ft()
    joint = feed.joint_slot()
    if joint is not None:
        joint["t_ns"], joint["device_t_ns"], joint["seq"] = t_of(i) + 7, 500 * i, 3 + i
        joint["q"], joint["qd"], joint["tau"] = axes_of(i, 1)[:6], axes_of(i, 2)[:6], -wrench_of(i)
    feed.commit_joint()
    tick = feed.tick_slot()
    if tick is not None:
        tick["t_ns"], tick["tick"] = t_of(i), i
        for field, name in enumerate(
            ("force", "offset", "offset_rate", "damping", "stiffness", "chi", "zeta")
        ):
            tick[name] = axes_of(i, field)
        tick["contact"] = np.arange(9) % 4
        tick["moment"] = wrench_of(i)[3:]
        tick["desired_position"] = wrench_of(i)[:3]
        tick["desired_orientation"] = (0.0, 0.0, math.sin(i), math.cos(i))
        tick["commanded_q"] = -axes_of(i, 3)[:6]
        tick["period_ns"], tick["compute_ns"], tick["lateness_ns"] = 1_000_000 + i, 200, i % 7
        tick["overruns"], tick["queue_drops"] = i // 100, 0
    feed.commit_tick()


def wait_until_drained(feed: RecorderFeed) -> None:
    """Until the recorder has read every committed row (at most 20 s)."""
    deadline = time.monotonic() + 20
    while feed.ft.backlog or feed.joint.backlog or feed.tick.backlog:
        assert time.monotonic() < deadline, "the recorder never caught up"
        time.sleep(0.01)


@pytest.fixture
def feed() -> Iterator[RecorderFeed]:
    with RecorderFeed() as feed:
        yield feed


def check_rows(frames: dict[str, Any], n: int) -> None:
    """Every topic of the hilrig loader holds rows 0..n-1 with the values pushed."""
    offset = session().clock_offset_ns
    t = np.array([t_of(i) for i in range(n)])
    i = np.arange(n)
    ft = frames["/ft/wrist"]
    assert list(ft.index) == list(t + offset)
    assert ft["sequence"].tolist() == list(range(n))  # no device sequence: a counter
    assert ft["wrench.force.x"].tolist() == (i + 0.0).tolist()
    assert ft["wrench.torque.z"].tolist() == (i + 2.5).tolist()
    joints = frames["/joint_states"]
    assert list(joints.index) == list(t + 7 + offset)
    assert joints["publish_time_ns"].tolist() == (500 * i).tolist()  # the robot's clock
    assert joints["sequence"].tolist() == (3 + i).tolist()
    assert joints["effort_5"].tolist() == (-(i + 2.5)).tolist()
    assert joints["velocity_0"].tolist() == (20 + i * 1e-3).tolist()
    state = frames["/controller/state"]
    assert state["axis_names_8"].iloc[0] == AXIS_NAMES[8]
    assert state["zeta_8"].tolist() == [axes_of(k, 6)[8] for k in range(n)]
    assert state["contact_state_7"].tolist() == [3] * n
    controller_input = frames["/controller/input"]
    assert controller_input["wrench.force.z"].tolist() == [axes_of(k, 0)[2] for k in range(n)]
    assert controller_input["wrench.torque.x"].tolist() == [wrench_of(k)[3] for k in range(n)]
    desired = frames["/trajectory/desired"]
    assert desired["pose.orientation.w"].tolist() == [math.cos(k) for k in range(n)]
    commanded = frames["/trajectory/commanded"]
    assert commanded["position_5"].tolist() == [-axes_of(k, 3)[5] for k in range(n)]
    assert "velocity_0" not in commanded
    loop = frames["/diagnostics/loop"]
    assert loop["period_ns"].tolist() == (1_000_000 + i).tolist()
    assert loop["overruns"].tolist() == (i // 100).tolist()


def official_messages(path: Path) -> tuple[Counter[str], dict[str, Any]]:
    """Per-topic counts and the last message of each topic, via mcap + mcap_ros2."""
    counts: Counter[str] = Counter()
    last: dict[str, Any] = {}
    with path.open("rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        assert "/ft/base" in {c.topic for c in summary.channels.values()}  # empty, yet declared
        for _, channel, _, message in reader.iter_decoded_messages(log_time_order=True):
            counts[channel.topic] += 1
            last[channel.topic] = message
    return counts, last


def test_every_row_and_event_reaches_its_topic_with_its_values(
    tmp_path: Path, feed: RecorderFeed
) -> None:
    path = tmp_path / "session.mcap"
    recorder = RecorderProcess(path, feed=feed, urdf=URDF, controller="adaptive")
    recorder.start(session())
    n = 1200
    push_rows(feed, 0, n // 2)
    assert recorder.pid is not None
    os.kill(recorder.pid, signal.SIGINT)  # Ctrl-C is the loop's business: ignored
    for k in range(3):
        feed.event(EventRecord(t_of(k * 100), EventKind.OPERATOR_MARK, "test", f"mark {k}"))
    push_rows(feed, n // 2, n)
    summary = recorder.stop()
    assert summary == (7 * n + 3, 0)
    assert recorder.stop() == summary

    frames = load(path)
    assert {t: len(frames[t]) for t in ROW_TOPICS} == dict.fromkeys(ROW_TOPICS, n)
    assert len(frames["/ft/base"]) == 0  # no source: an empty channel
    assert frames["/events"]["detail"].tolist() == ["mark 0", "mark 1", "mark 2"]
    assert len(frames["/robot_description"]) == 1
    check_rows(frames, n)

    counts, last = official_messages(path)
    assert counts == Counter(
        {**dict.fromkeys(ROW_TOPICS, n), "/events": 3, "/robot_description": 1}
    )
    i = n - 1
    assert last["/ft/wrist"].wrench.torque.y == i + 2.0
    assert list(last["/joint_states"].position) == axes_of(i, 1)[:6].tolist()
    assert list(last["/controller/state"].axis_names) == list(AXIS_NAMES)
    assert list(last["/controller/state"].stiffness) == axes_of(i, 4).tolist()
    assert last["/controller/input"].wrench.torque.y == wrench_of(i)[4]
    assert last["/trajectory/desired"].pose.position.z == i + 1.0
    assert list(last["/trajectory/commanded"].velocity) == []
    assert last["/diagnostics/loop"].lateness_ns == i % 7
    assert last["/events"].kind == EventKind.OPERATOR_MARK


def test_killed_recorder_file_recovers_losing_at_most_half_a_second(
    tmp_path: Path, feed: RecorderFeed
) -> None:
    path = tmp_path / "killed.mcap"
    recorder = RecorderProcess(path, feed=feed)
    recorder.start(session())
    n = 1500
    push_rows(feed, 0, n)
    wait_until_drained(feed)
    recorder.kill()
    assert not inspect(path).complete

    recovery = recover(path, tmp_path / "recovered.mcap")
    assert not recovery.was_complete
    frames = load(recovery.output)
    last_pushed = t_of(n - 1) + session().clock_offset_ns
    for topic in ROW_TOPICS:
        kept = len(frames[topic])
        assert kept >= n - 500, topic  # 0.5 s at 1 kHz
        assert frames[topic].index[-1] >= last_pushed - 500_000_000, topic
    kept = min(len(frames[topic]) for topic in ROW_TOPICS)
    check_rows({t: frames[t].iloc[:kept] for t in ROW_TOPICS}, kept)


def test_rows_of_a_paused_loop_reach_the_disk(tmp_path: Path, feed: RecorderFeed) -> None:
    path = tmp_path / "paused.mcap"
    recorder = RecorderProcess(path, feed=feed)
    recorder.start(session())
    push_rows(feed, 0, 20, paced=False)  # far less than a chunk's 0.25 s of log time
    deadline = time.monotonic() + 20
    while inspect(path).chunks == 0:  # written once the recorder has been idle a while
        assert time.monotonic() < deadline, "the open chunk never reached the file"
        time.sleep(0.05)
    recorder.kill()
    frames = load(recover(path, tmp_path / "recovered.mcap").output)
    assert {t: len(frames[t]) for t in ROW_TOPICS} == dict.fromkeys(ROW_TOPICS, 20)


def test_stalled_recorder_makes_the_feed_drop_instead_of_blocking(tmp_path: Path) -> None:
    path = tmp_path / "stalled.mcap"
    with RecorderFeed(rows=16, events=4) as feed:
        recorder = RecorderProcess(path, feed=feed)
        recorder.start(session())
        assert recorder.pid is not None
        os.kill(recorder.pid, signal.SIGSTOP)
        try:
            push_rows(feed, 0, 40, paced=False)  # returns although nobody reads
            accepted = [
                feed.event(EventRecord(t_of(k), EventKind.FAULT, "test")) for k in range(10)
            ]
            assert accepted == [True] * 4 + [False] * 6
            assert feed.drops == 3 * (40 - 16) + 6
            assert (feed.ft.dropped, feed.joint.dropped, feed.tick.dropped) == (24, 24, 24)
        finally:
            os.kill(recorder.pid, signal.SIGCONT)
        summary = recorder.stop()
    assert summary == (16 * 7 + 4, 78)
    frames = load(path)
    assert len(frames["/diagnostics/loop"]) == 16
    assert len(frames["/events"]) == 4


def test_sigterm_finishes_the_file(tmp_path: Path, feed: RecorderFeed) -> None:
    path = tmp_path / "terminated.mcap"
    recorder = RecorderProcess(path, feed=feed)
    recorder.start(session())
    push_rows(feed, 0, 50, paced=False)
    wait_until_drained(feed)
    assert recorder.pid is not None
    os.kill(recorder.pid, signal.SIGTERM)
    assert recorder.stop() == (50 * 7, 0)
    assert inspect(path).complete


def test_existing_file_is_refused_at_start(tmp_path: Path, feed: RecorderFeed) -> None:
    path = tmp_path / "taken.mcap"
    path.write_bytes(b"")
    recorder = RecorderProcess(path, feed=feed)
    with pytest.raises(RecordingError, match="already exists") as raised:
        recorder.start(session())
    assert "\n" not in str(raised.value)


def loop_process(path: Path, done: Connection) -> None:
    """A loop process that records 200 rows, then dies without stopping its recorder."""
    feed = RecorderFeed()
    recorder = RecorderProcess(path, feed=feed)
    recorder.start(session())
    push_rows(feed, 0, 200, paced=False)
    # Free the rings' names (the recorder keeps its handles), then die at once.
    feed.close()
    del feed, recorder
    gc.collect()
    done.send(None)
    os._exit(0)


def test_recorder_finishes_its_file_when_the_loop_process_dies(tmp_path: Path) -> None:
    path = tmp_path / "orphan.mcap"
    context = multiprocessing.get_context("spawn")
    receive, send = context.Pipe(duplex=False)
    loop = context.Process(target=loop_process, args=(path, send))
    loop.start()
    receive.recv()
    loop.join(20)
    deadline = time.monotonic() + 20
    while not (path.exists() and inspect(path).complete):
        assert time.monotonic() < deadline, "the orphaned recorder never finished its file"
        time.sleep(0.05)
    frames = load(path)
    assert {t: len(frames[t]) for t in ROW_TOPICS} == dict.fromkeys(ROW_TOPICS, 200)
