"""The live view of ``hilrig record --view``: the recorder's decimated copy, its batches in Rerun
(read back from the ``.rrd`` with Rerun's own reader), a recorder whose view nobody reads, and
sessions streaming to a real Rerun gRPC server or to a viewer that is not there, each with its
recording complete."""

from __future__ import annotations

import multiprocessing
import socket
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import nullcontext
from multiprocessing.queues import Queue
from pathlib import Path

import numpy as np
import pytest
from rrd_helpers import Rrd
from servers import impostor, rerun_save_server

from hilrig.errors import ViewError
from hilrig.recording import EventKind, EventRecord, SessionInfo, inspect, load
from hilrig.recording.samples import ContactState
from hilrig.rig import (
    AXIS_NAMES,
    FT_DTYPE,
    JOINT_DTYPE,
    START_METHOD,
    TICK_DTYPE,
    RecorderFeed,
    RecorderProcess,
    SessionConfig,
    SessionResult,
    ViewBatch,
    ViewForwarder,
    record_session,
)
from hilrig.rig.view_feed import first_per_period
from hilrig.robot.model import RobotModel
from hilrig.viz import paths
from hilrig.viz.live import LiveView, check_sink, event_line
from hilrig.viz.log import FORCE_SCALE_M_PER_N
from hilrig.viz.scene import RECORDED
from hilrig.viz.sinks import Sink, SinkKind, grpc_url

T0_NS = 1_000_000_000_000  # a multiple of 20 ms: every 20th row starts a period
TICK_NS = 1_000_000
TICKS = 1000  # 1 s at 1 kHz: 50 rows at 50 Hz
KEPT = np.arange(0, TICKS, 20)
GROUPS = ("end effector", "body")
SERIES = (
    {paths.input_series(a) for a in AXIS_NAMES}
    | {paths.run_series(q, a, RECORDED) for q in paths.QUANTITIES for a in AXIS_NAMES}
    | {paths.wrist_series(c) for c in paths.WRIST_CHANNELS}
    | {paths.joint_series(f"joint{j + 1}") for j in range(6)}
)
LIVE_ENTITIES = (
    SERIES
    | {paths.contact_lane(g, RECORDED) for g in GROUPS}
    | {paths.ROBOT_LINKS, paths.ROBOT_JOINTS, paths.FORCE_ARROW, paths.EVENTS}
    | {
        f"{folder}/now"
        for folder in (
            paths.trajectory(paths.DESIRED),
            paths.trajectory(paths.ACTUAL),
            paths.run_trajectory(RECORDED),
        )
    }
)
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


def read(path: Path) -> Rrd:
    with warnings.catch_warnings():  # `rerun --save` writes no footer: read it whole
        warnings.simplefilter("ignore")
        return Rrd(path)


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


# -- sessions -----------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@pytest.fixture(scope="module")
def streamed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[SessionResult, Path]]:
    """A 3 s session streaming its live view to ``rerun --save`` (Rerun's gRPC server, no
    window) on loopback; the server's file once it has stopped."""
    tmp = tmp_path_factory.mktemp("streamed")
    saved = tmp / "server.rrd"
    with rerun_save_server(saved) as url:
        result = session(tmp / "session.mcap", 3.0, Sink(SinkKind.CONNECT, url=url))
    yield result, saved


def session(out: Path, seconds: float, view: Sink | None) -> SessionResult:
    config = SessionConfig(out=out, subject_id="S001", duration_s=seconds, session_id="live")
    live = None
    if view is not None:
        live = LiveView(
            view,
            session_id=config.session_id,
            controller=config.loop.law.value,
            source=out.name,
            urdf=RobotModel().urdf_xml,
        )
    return record_session(config, stop=threading.Event(), live=live)


def assert_recording_complete(result: SessionResult) -> None:
    """Every tick on every 1 kHz topic, no tick missing, nothing dropped, closed cleanly."""
    assert result.recorder_error == "" and result.drops == 0
    assert inspect(result.path).complete
    frames = load(result.path)
    ticks = frames["/diagnostics/loop"]["tick"].to_numpy()
    assert len(ticks) == result.summary.ticks and (np.diff(ticks) == 1).all()
    for topic in ("/controller/input", "/controller/state", "/trajectory/desired"):
        assert len(frames[topic]) == result.summary.ticks, topic
    written = sum(len(f) for t, f in frames.items() if t != "/robot_description")
    assert result.messages_written == written


def test_a_session_streams_its_live_view_to_a_rerun_server(
    streamed: tuple[SessionResult, Path],
) -> None:
    result, saved = streamed
    view = result.view
    assert view is not None and view.problem == ""
    assert view.dropped == 0 and view.shown == view.sent >= 10  # 3 s in 0.1 s batches (or fewer)
    rrd = read(saved)
    assert rrd.entities(static=False) >= LIVE_ENTITIES
    state = load(result.path, topics=["/controller/state"])["/controller/state"]
    t_ns = state.index.to_numpy() - state.index[0]  # the file's log times share the zero
    duration_s = t_ns[-1] / 1e9  # the ticks' span (a loaded machine may merge some frames)
    t, force = rrd.scalars(paths.input_series("x"))
    assert len(t) == pytest.approx(50 * duration_s, abs=3)
    assert t.min() >= 0 and t.max() <= duration_s
    rows = np.searchsorted(t_ns, np.round(t * 1e9).astype(np.int64))
    np.testing.assert_allclose(t_ns[rows] / 1e9, t, rtol=0, atol=2e-9)
    assert force.tolist() == state["force_0"].to_numpy()[rows].tolist()
    t_events, _ = rrd.temporal(paths.EVENTS, "TextLog:text")
    assert len(t_events) == len(result.events)


def test_the_recording_with_a_live_view_is_complete(streamed: tuple[SessionResult, Path]) -> None:
    assert_recording_complete(streamed[0])


@pytest.mark.parametrize(
    "silent", [False, True], ids=["nothing listens", "a server that never answers"]
)
def test_a_viewer_that_is_not_there_is_reported_once_and_the_session_goes_on(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], silent: bool
) -> None:
    with impostor(None) if silent else nullcontext(grpc_url(free_port())) as url:
        result = session(tmp_path / "s.mcap", 2.0, Sink(SinkKind.CONNECT, url=url))
    assert result.view is not None and result.view.shown == 0
    why = (
        "nothing answering like a Rerun viewer there (no answer within 2 s)"
        if silent
        else "no viewer listening there (Connection refused)"
    )
    assert result.view.problem == f"{url}: {why}"
    assert capfd.readouterr().err.count("live view:") == 1
    ticks = load(result.path, topics=["/diagnostics/loop"])["/diagnostics/loop"]
    span_s = (ticks.index[-1] - ticks.index[0]) / 1e9
    assert span_s > 1.5  # the session went on to its end (2 s of its clock), however slowly
    assert_recording_complete(result)


def test_live_view_start_and_stop_without_a_recorder_report_nothing_sent(
    tmp_path: Path,
) -> None:
    live = LiveView(
        Sink(SinkKind.SAVE, path=tmp_path / "idle.rrd"),
        session_id="idle",
        controller="fixed",
        source="idle.mcap",
    )
    live.start()
    report = live.stop(None)
    assert (report.sent, report.dropped, report.shown) == (0, 0, 0)
    assert report.problem == "the recorder did not report on the view"
    assert "idle" in read(tmp_path / "idle.rrd").static(paths.ABOUT, "TextDocument:text")[0]
