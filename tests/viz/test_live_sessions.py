"""Sessions of ``hilrig record --view`` end to end: streaming to a real Rerun gRPC server
(``rerun --save`` on loopback), or to a viewer that is not there, each with its recording
complete; and a live view started and stopped without a recorder."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import pytest
from live_helpers import LIVE_ENTITIES, read
from servers import impostor

from hilrig.recording import inspect, load
from hilrig.rig import SessionConfig, SessionResult, record_session
from hilrig.robot.model import RobotModel
from hilrig.timing import realtime_permitted
from hilrig.viz import paths
from hilrig.viz.live import LiveView
from hilrig.viz.live_feed import NICENESS
from hilrig.viz.save_server import rerun_save_server
from hilrig.viz.sinks import Sink, SinkKind, grpc_url


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
    assert t.min() >= 0 and t.max() <= duration_s
    rows = np.searchsorted(t_ns, np.round(t * 1e9).astype(np.int64))
    np.testing.assert_allclose(t_ns[rows] / 1e9, t, rtol=0, atol=2e-9)
    # the first tick of every 20 ms period on the loop's clock, whose phase the file does not
    # keep: some placement of the periods' bounds gives exactly these ticks (not a count from
    # the rate: a stall of a slow machine leaves whole periods without a tick)
    period_ns = 20_000_000
    firsts = [
        np.flatnonzero(np.diff((t_ns + phase) // period_ns, prepend=-1) != 0)
        for phase in np.unique(-t_ns % period_ns)
    ]
    assert any(np.array_equal(kept, rows) for kept in firsts)
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
    pid = live._child.pid
    assert pid is not None
    # niced only where the loop cannot run SCHED_FIFO: a niced feed starved on a busy machine
    niceness = os.getpriority(os.PRIO_PROCESS, pid)
    report = live.stop(None)
    assert niceness == (0 if realtime_permitted() else NICENESS)
    assert (report.sent, report.dropped, report.shown) == (0, 0, 0)
    assert report.problem == "the recorder did not report on the view"
    assert "idle" in read(tmp_path / "idle.rrd").static(paths.ABOUT, "TextDocument:text")[0]
