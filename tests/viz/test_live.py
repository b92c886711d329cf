"""The live view of ``hilrig record --view``: the recorder's decimated copy, its batches in Rerun
(read back from the ``.rrd`` with Rerun's own reader) and a recorder whose view nobody reads.
Whole sessions with a live view: test_live_sessions.py."""

from __future__ import annotations

import fcntl
import multiprocessing
import os
import signal
import threading
import time
from multiprocessing.queues import Queue
from pathlib import Path

import numpy as np
import pytest
from live_helpers import LIVE_ENTITIES, read
from rrd_helpers import Rrd

from hilrig.errors import ViewError
from hilrig.recording import EventKind, EventRecord, SessionInfo
from hilrig.recording.samples import ContactState
from hilrig.rig import (
    AXIS_NAMES,
    FT_DTYPE,
    JOINT_DTYPE,
    START_METHOD,
    TICK_DTYPE,
    RecorderFeed,
    RecorderProcess,
    ViewBatch,
    ViewCounts,
    ViewForwarder,
)
from hilrig.rig.view_feed import first_per_period
from hilrig.robot.model import RobotModel
from hilrig.viz import paths
from hilrig.viz.live import KEEP_S, PIPE_BYTES, LiveView, check_sink, event_line
from hilrig.viz.log import FORCE_SCALE_M_PER_N
from hilrig.viz.scene import RECORDED
from hilrig.viz.sinks import Sink, SinkKind

T0_NS = 1_000_000_000_000  # a multiple of 20 ms: every 20th row starts a period
TICK_NS = 1_000_000
TICKS = 1000  # 1 s at 1 kHz: 50 rows at 50 Hz
KEPT = np.arange(0, TICKS, 20)
EVENTS = (
    EventRecord(T0_NS - 5_000_000, EventKind.OPERATOR_MARK, "loop", "session started"),
    EventRecord(T0_NS + 300 * TICK_NS, EventKind.COLLISION_START, "controller", "", "x", 4.5),
    EventRecord(T0_NS + 700 * TICK_NS, EventKind.FAULT, "wrist F/T sensor", "stale"),
)


def rows(n: int = TICKS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wrist F/T, joint-state and tick rows of a synthetic 1 kHz session, every value known."""
    i = np.arange(n)
    t = T0_NS + i * TICK_NS
    ft = np.zeros(n, FT_DTYPE)
    ft["t_ns"], ft["seq"] = t + 3, i
    ft["wrench"] = i[:, None] * 0.01 + np.arange(6)
    joints = np.zeros(n, JOINT_DTYPE)
    joints["t_ns"], joints["seq"] = t + 7, i
    joints["q"] = np.array([0.0, -0.3, 1.2, 0.4, 1.57, 0.0]) + i[:, None] * 1e-3
    ticks = np.zeros(n, TICK_DTYPE)
    ticks["t_ns"], ticks["tick"] = t, i
    for k, field in enumerate(("force", "offset", "damping", "stiffness", "zeta")):
        ticks[field] = np.sin(i[:, None] * 0.01 + k) + np.arange(9) * 0.1
    ticks["contact"][:, :3] = np.select(
        [i < 300, i < 600, i < 800],
        [ContactState.FREE, ContactState.CONTACT, ContactState.HOLDING],
        ContactState.RECOVERING,
    )[:, None]
    ticks["desired_position"] = np.array([0.5, -0.1, 0.4]) + i[:, None] * 1e-4
    return ft, joints, ticks


def spawn_queue(size: int = 0) -> Queue[ViewBatch | None]:
    return multiprocessing.get_context(START_METHOD).Queue(size)


def feed_rows(
    forwarder: ViewForwarder,
    rows: tuple[np.ndarray, np.ndarray, np.ndarray],
    collect: list[ViewBatch] | None = None,
) -> None:
    """Hand the rows and EVENTS to ``forwarder`` as the recorder does (5 rows per read, the
    batches due by the rows' own clock); read each batch it sends back into ``collect``."""
    ft, joints, ticks = rows
    forwarder.event(EVENTS[0])  # before the first tick: held until it comes
    for start in range(0, len(ticks), 5):
        for stream, r in (("ft", ft), ("joints", joints), ("ticks", ticks)):
            forwarder.rows_read(stream, r[start : start + 5])
        for event in EVENTS[1:]:
            if ticks["t_ns"][start] <= event.t_ns < ticks["t_ns"][start] + 5 * TICK_NS:
                forwarder.event(event)
        forwarder.send_due(int(ticks["t_ns"][start]))
        if collect is not None:
            collect += [
                forwarder.queue.get(timeout=10) for _ in range(forwarder.sent - len(collect))
            ]


def test_a_period_keeps_its_first_row_and_the_next_read_continues_it() -> None:
    t_ns = np.array([0, 5, 19, 20, 21, 45, 60, 79], dtype=np.int64)
    keep, last = first_per_period(t_ns, 20)
    assert keep.tolist() == [0, 3, 5, 6] and last == 3
    keep, last = first_per_period(np.array([70, 80, 99], dtype=np.int64), 20, last)
    assert keep.tolist() == [1] and last == 4  # 70 is in the period of 60 and 79: not again


def test_the_recorder_forwards_every_20_ms_row_and_every_event_in_100_ms_batches() -> None:
    sent = rows()
    forwarder = ViewForwarder(spawn_queue(), rate_hz=50, batch_s=0.1)
    batches: list[ViewBatch] = []
    feed_rows(forwarder, sent, batches)
    forwarder.send_due(T0_NS + 10**9)  # the rest
    batches += [forwarder.queue.get(timeout=10) for _ in range(forwarder.sent - len(batches))]
    assert len(batches) == pytest.approx(10, abs=1)  # 1 s in batches of 0.1 s
    assert {b.t0_ns for b in batches} == {T0_NS}
    for name, r in zip(("ft", "joints", "ticks"), sent, strict=True):
        got = np.concatenate([getattr(b, name) for b in batches])
        assert got.tobytes() == r[KEPT].tobytes(), name
    assert [repr(e) for b in batches for e in b.events] == [repr(e) for e in EVENTS]  # NaNs
    assert forwarder.finish(1.0) == (len(batches), 0, "")


def test_a_full_view_queue_drops_batches_and_the_forwarder_never_waits() -> None:
    ticks = rows(200)[2]
    q = spawn_queue(1)  # nobody reads it
    forwarder = ViewForwarder(q, rate_hz=50, batch_s=0.0)
    for start in range(0, 200, 20):
        forwarder.rows_read("ticks", ticks[start : start + 20])
        forwarder.send_due(0)
    started = time.monotonic()
    counts = forwarder.finish(0.5)
    assert time.monotonic() - started < 5  # bounded by the hand-over timeout, not the reader
    assert (counts.sent, counts.dropped, counts.error) == (1, 9, "")


def test_a_feed_behind_at_the_end_shows_what_is_queued_and_writes_its_file(
    tmp_path: Path,
) -> None:
    """On a loaded machine the queue is full when the session ends, so the recorder's end
    marker is dropped: the session's word that it ended, sent beside the queue, ends the feed
    once it has shown what is queued (it would wait on, be killed after FINISH_S, and its file
    would not be written)."""
    path = tmp_path / "live.rrd"
    live, feed_pid = started_view(path, "behind", queue_batches=3)
    os.kill(feed_pid, signal.SIGSTOP)  # a feed that has fallen behind: it reads nothing now
    forwarder = ViewForwarder(live.queue, rate_hz=50, batch_s=0.1)
    feed_rows(forwarder, rows())
    # the recorder's end, in its own process (here its finish would close the view's queue):
    # its marker is dropped as the queue is full
    assert forwarder.queue.full() and forwarder.dropped > 0
    counts = ViewCounts(forwarder.sent, forwarder.dropped, "")
    threading.Timer(0.5, os.kill, (feed_pid, signal.SIGCONT)).start()
    report = live.stop(counts)
    assert (report.problem, report.shown) == ("", 3)
    assert path.exists()


def test_a_feed_still_behind_when_its_time_is_up_keeps_the_session_up_to_there(
    tmp_path: Path,
) -> None:
    """A feed that cannot show the queue in the time the session gives it stops there, writes
    its file with what it showed (a prefix of the session, whole) and says what it left."""
    path = tmp_path / "live.rrd"
    live, feed_pid = started_view(path, "late")
    forwarder = ViewForwarder(live.queue, rate_hz=50, batch_s=0.1)
    ft, joints, ticks = rows()
    feed_rows(forwarder, (ft[:500], joints[:500], ticks[:500]))
    first = forwarder.sent
    wait_until_read(live.queue)
    os.kill(feed_pid, signal.SIGSTOP)  # behind from here on
    feed_rows(forwarder, (ft[500:], joints[500:], ticks[500:]))
    assert forwarder.dropped == 0 and forwarder.sent > first
    counts = ViewCounts(forwarder.sent, forwarder.dropped, "")
    threading.Timer(2.0, os.kill, (feed_pid, signal.SIGCONT)).start()  # after its 1 s is up
    report = live.stop(counts, timeout_s=KEEP_S + 1.0)
    # every batch it took before the stop is shown, but one it took and had not yet shown
    assert first - 1 <= report.shown <= first
    left = forwarder.sent - report.shown
    assert report.problem == f"{left} batches not shown: still behind 1 s after the end"
    _, force = read(path).scalars(paths.input_series("x"))
    assert 0 < len(force) < len(KEPT)
    assert force.tolist() == ticks["force"][KEPT[: len(force)], 0].tolist()


def started_view(path: Path, session_id: str, queue_batches: int = 50) -> tuple[LiveView, int]:
    """A live view saving to ``path``, started, and its feed's pid."""
    live = LiveView(
        Sink(SinkKind.SAVE, path=path),
        session_id=session_id,
        controller="adaptive",
        source="session.mcap",
        queue_batches=queue_batches,
    )
    live.start()
    assert live._child.pid is not None
    return live, live._child.pid


def wait_until_read(q: Queue[ViewBatch | None], timeout_s: float = 60.0) -> None:
    """Until the queue was seen empty five times in a row 0.1 s apart (its feeder thread in
    this process has handed everything over and the feed took it)."""
    deadline, seen = time.monotonic() + timeout_s, 0
    while seen < 5:
        assert time.monotonic() < deadline, "the feed read nothing in 60 s"
        seen = seen + 1 if q.empty() else 0
        time.sleep(0.1)


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> tuple[Rrd, np.ndarray, np.ndarray]:
    """The rows of :func:`rows` through a forwarder and a live view's feed process into an .rrd
    file, as a session with ``--view-save`` sends them."""
    sent = rows()
    path = tmp_path_factory.mktemp("live") / "live.rrd"
    live = LiveView(
        Sink(SinkKind.SAVE, path=path),
        session_id="live-test",
        controller="adaptive",
        source="session.mcap",
    )
    live.start()
    forwarder = ViewForwarder(live.queue, rate_hz=50, batch_s=0.1)
    feed_rows(forwarder, sent)
    report = live.stop(forwarder.finish(5.0))
    assert report.problem == "" and report.shown == report.sent >= 10
    return read(path), sent[1], sent[2]


def test_the_live_view_logs_the_entity_tree_of_a_files_view_without_whole_paths(
    saved: tuple[Rrd, np.ndarray, np.ndarray],
) -> None:
    rrd, _, _ = saved
    assert rrd.entities(static=False) - {"/__properties"} == LIVE_ENTITIES
    assert not any(e.endswith("/path") for e in rrd.entities())
    assert "50 Hz" in rrd.static(paths.ABOUT, "TextDocument:text")[0]
    assert rrd.static(paths.run_series("offset", "x", RECORDED), "SeriesLines:names") == [
        "recorded (adaptive)"
    ]
    assert rrd.recordings[0].recording_id == "live-test"


def test_every_series_holds_its_rows_at_50_hz_with_their_values_and_times(
    saved: tuple[Rrd, np.ndarray, np.ndarray],
) -> None:
    rrd, joints, ticks = saved
    t_s = (ticks["t_ns"][KEPT] - T0_NS) / 1e9
    for i, axis in enumerate(AXIS_NAMES):
        t, force = rrd.scalars(paths.input_series(axis))
        np.testing.assert_allclose(t, t_s, rtol=0, atol=2e-9)
        assert force.tolist() == ticks["force"][KEPT, i].tolist()
        for quantity in paths.QUANTITIES:
            t, values = rrd.scalars(paths.run_series(quantity, axis, RECORDED))
            assert len(t) == len(KEPT)
            assert values.tolist() == ticks[quantity][KEPT, i].tolist(), (quantity, axis)
    t, q1 = rrd.scalars(paths.joint_series("joint2"))
    np.testing.assert_allclose(t, t_s + 7e-9, rtol=0, atol=2e-9)
    assert q1.tolist() == joints["q"][KEPT, 1].tolist()
    _, fz = rrd.scalars(paths.wrist_series("fz"))
    assert len(fz) == len(KEPT)


def test_contact_lanes_change_state_only_when_it_changes_across_batches(
    saved: tuple[Rrd, np.ndarray, np.ndarray],
) -> None:
    rrd, _, _ = saved
    t, states = rrd.temporal(paths.contact_lane("end effector", RECORDED), "StateChange:state")
    assert [s[0] for s in states] == ["free", "contact", "holding", "recovering"]
    np.testing.assert_allclose(t, [0.0, 0.3, 0.6, 0.8], rtol=0, atol=2e-9)
    _, body = rrd.temporal(paths.contact_lane("body", RECORDED), "StateChange:state")
    assert body == [["free"]]


def test_the_robot_force_and_markers_follow_the_latest_joint_row_at_each_tick(
    saved: tuple[Rrd, np.ndarray, np.ndarray],
) -> None:
    rrd, joints, ticks = saved
    model = RobotModel()
    # joint rows arrive 7 ns after their tick: the latest kept one is the previous period's
    q_rows = np.maximum(KEPT - 20, 0)
    links = np.array([model.link_points(joints["q"][r]) for r in q_rows])
    _, strips = rrd.temporal(paths.ROBOT_LINKS, "LineStrips3D:strips")
    np.testing.assert_allclose(np.array([s[0] for s in strips]), links, atol=1e-6)
    _, arrows = rrd.temporal(paths.FORCE_ARROW, "Arrows3D:vectors")
    force = ticks["force"][KEPT, :3] * FORCE_SCALE_M_PER_N
    np.testing.assert_allclose(np.array([a[0] for a in arrows]), force, rtol=1e-6, atol=2e-9)
    _, origins = rrd.temporal(paths.FORCE_ARROW, "Arrows3D:origins")
    np.testing.assert_allclose(np.array([o[0] for o in origins]), links[:, -1], atol=1e-6)
    _, actual = rrd.temporal(f"{paths.trajectory(paths.ACTUAL)}/now", "Points3D:positions")
    np.testing.assert_allclose(np.array([p[0] for p in actual]), links[:, -1], atol=1e-6)
    desired = ticks["desired_position"][KEPT]
    reference = desired + ticks["offset"][KEPT, :3]
    for folder, expected in (
        (paths.trajectory(paths.DESIRED), desired),
        (paths.run_trajectory(RECORDED), reference),
    ):
        _, now = rrd.temporal(f"{folder}/now", "Points3D:positions")
        np.testing.assert_allclose(np.array([p[0] for p in now]), expected, atol=1e-6)


def test_every_event_is_logged_with_its_time_text_and_level(
    saved: tuple[Rrd, np.ndarray, np.ndarray],
) -> None:
    rrd, _, _ = saved
    t, text = rrd.temporal(paths.EVENTS, "TextLog:text")
    _, level = rrd.temporal(paths.EVENTS, "TextLog:level")
    np.testing.assert_allclose(t, [(e.t_ns - T0_NS) / 1e9 for e in EVENTS], atol=2e-9)
    assert [(x[0], lv[0]) for x, lv in zip(text, level, strict=True)] == [
        event_line(e) for e in EVENTS
    ]
    assert event_line(EVENTS[1]) == ("[controller] collision start: x (4.5)", "WARN")
    assert event_line(EVENTS[2]) == ("[wrist F/T sensor] fault: stale", "ERROR")


@pytest.mark.parametrize(
    ("sink", "message"),
    [
        (Sink(SinkKind.CONNECT, url="http://127.0.0.1:9876/proxy"), "expected rerun\\+http"),
        (Sink(SinkKind.CONNECT, url="rerun+http://127.0.0.1:9876/"), "expected rerun\\+http"),
        (Sink(SinkKind.CONNECT, url="rerun+http://127.0.0.1:99999/proxy"), "expected"),
        (Sink(SinkKind.SAVE, path=Path("/no/such/dir/live.rrd")), "does not exist"),
        (Sink(SinkKind.SAVE, path=Path("live.mcap")), "must end in .rrd"),
        (Sink(SinkKind.WEB), "rerun --serve-web"),
    ],
)
def test_a_destination_the_live_view_cannot_use_is_refused_in_one_line(
    sink: Sink, message: str
) -> None:
    with pytest.raises(ViewError, match=message) as caught:
        check_sink(sink)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("slots", [2, 1000])
def test_a_recorder_whose_view_nobody_reads_records_every_row_and_stops_in_time(
    tmp_path: Path, slots: int
) -> None:
    """2 slots: the queue is full at once, batches are dropped. 1000: the batches fill the
    pipe under the queue (64 KiB) and its thread blocks, which must not keep the recorder."""
    sent = rows(3000)
    q = spawn_queue(slots)
    with RecorderFeed() as feed:
        recorder = RecorderProcess(tmp_path / "s.mcap", feed=feed, view=q)
        recorder.start(session_info())
        for start in range(0, 3000, 100):
            push(feed, sent, start, start + 100)
            time.sleep(0.1)  # paced: about 1 kHz
        summary = recorder.stop()
    assert summary == (3000 * 7, 0)  # every row of every ring, nothing refused
    assert recorder.view_counts is not None
    batches, dropped, error = recorder.view_counts
    assert error == ""
    assert batches + dropped >= 25  # 3 s in batches of 0.1 s
    assert batches == 2 if slots == 2 else dropped == 0
    q.cancel_join_thread()


def test_a_recorder_ending_while_its_feed_is_behind_hands_over_every_batch_it_sent(
    tmp_path: Path,
) -> None:
    """The feed reads nothing while a recorder sends 3 s of batches (30, the queue holds 50)
    and exits: every batch is in the queue's pipe by then, none left in the recorder's queue
    thread to die with it (Linux's 64 KiB pipe held 10), and the feed shows them all."""
    path = tmp_path / "live.rrd"
    live, feed_pid = started_view(path, "handover")
    os.kill(feed_pid, signal.SIGSTOP)
    sent = rows(3000)
    with RecorderFeed() as feed:
        recorder = RecorderProcess(tmp_path / "s.mcap", feed=feed, view=live.queue)
        recorder.start(session_info())
        for start in range(0, 3000, 100):
            push(feed, sent, start, start + 100)
            time.sleep(0.1)
        assert recorder.stop() == (3000 * 7, 0)
    os.kill(feed_pid, signal.SIGCONT)
    counts = recorder.view_counts
    assert counts is not None and counts.dropped == 0 and counts.sent >= 25
    report = live.stop(counts)
    assert (report.problem, report.shown, report.sent) == ("", counts.sent, counts.sent)
    _, force = read(path).scalars(paths.input_series("x"))
    assert force.tolist() == sent[2]["force"][::20, 0].tolist()


def test_the_view_queues_pipe_is_widened_to_hold_every_batch_it_admits(tmp_path: Path) -> None:
    """The queue's pipe (reached through multiprocessing's private ``_writer``) is widened: a
    Python whose queue hid it would leave Linux's 64 KiB, which the test above shows losing
    batches."""
    live = LiveView(
        Sink(SinkKind.SAVE, path=tmp_path / "v.rrd"),
        session_id="pipe",
        controller="adaptive",
        source="session.mcap",
    )
    writer = live.queue._writer  # type: ignore[attr-defined]
    assert fcntl.fcntl(writer.fileno(), fcntl.F_GETPIPE_SZ) == PIPE_BYTES


def push(feed: RecorderFeed, sent: tuple[np.ndarray, ...], start: int, stop: int) -> None:
    """Commit rows ``start..stop-1`` of each of ``sent`` to its ring, as the loop does."""
    for (reserve, commit), r in zip(
        (
            (feed.ft_slot, feed.commit_ft),
            (feed.joint_slot, feed.commit_joint),
            (feed.tick_slot, feed.commit_tick),
        ),
        sent,
        strict=True,
    ):
        for i in range(start, stop):
            slot = reserve()
            assert slot is not None
            slot[...] = r[i]
            commit()


def session_info() -> SessionInfo:
    return SessionInfo(
        session_id="live-recorder",
        subject_id="S012",
        rig="emulated",
        controller="adaptive",
        start_utc_ns=1_767_225_600_000_000_000,
        start_monotonic_ns=T0_NS,
    )
