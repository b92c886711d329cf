"""The live view of ``hilrig record --view``: the session in Rerun while it is recorded.

The loop does nothing for it. The recorder process, which reads every row anyway, forwards a
copy decimated to 50 Hz (:class:`~hilrig.rig.view_feed.ViewForwarder`) in batches over a
bounded queue, never waiting: a full queue drops the batch. The viewer-feed process started by
:class:`LiveView` (niced, so the loop's processes come first) turns the batches into the entity
tree of a file's view (:mod:`.paths`, the recorded controller as run ``recorded``) and streams
them to the desktop viewer, a viewer or server at a URL, or an ``.rrd`` file. A viewer that
cannot be reached, or stops taking data, is reported once; the feed then ends and the session
goes on recording everything.
"""

from __future__ import annotations

import contextlib
import os
import queue
import socket
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.queues import Queue
from typing import NoReturn

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hilrig.errors import ViewError
from hilrig.recording.samples import EventRecord
from hilrig.rig import (
    AXIS_NAMES,
    VIEW_RATE_HZ,
    ChildProcess,
    LiveViewPort,
    Rows,
    ViewBatch,
    ViewCounts,
)
from hilrig.rig.child import CONTEXT, report
from hilrig.robot.model import RobotModel
from hilrig.viz import paths, style
from hilrig.viz.blueprint import blueprint
from hilrig.viz.decimate import Decimation
from hilrig.viz.log import (
    FORCE_SCALE_M_PER_N,
    RunStyle,
    latest_at,
    log_styles,
    send_contact,
    send_events,
    send_force,
    send_marker,
    send_robot,
    send_scalars,
)
from hilrig.viz.scene import RECORDED, group_columns
from hilrig.viz.scene import event_line as scene_event_line
from hilrig.viz.sinks import Sink, SinkKind, check_rrd_path, grpc_address, open_stream

FloatArray = NDArray[np.float64]

QUEUE_BATCHES = 50  # 5 s of batches: a viewer stalled longer costs dropped batches
START_S = 30.0  # the feed's start-up (imports, the stream, a spawned viewer)
FINISH_S = 10.0  # the feed's last flush after the session
POLL_S = 0.2  # the feed checks on its parent this often while no batch comes
CHECK_S = 1.0  # the stream's health (a flush) is checked this often
FLUSH_TIMEOUT_S = 5.0
CONNECT_TIMEOUT_S = 2.0
NICENESS = 10


@dataclass(frozen=True)
class LiveReport:
    """How a live view went: batches the recorder ``sent`` and ``dropped`` (queue full),
    batches ``shown`` (logged to the stream), and the ``problem`` that ended it ("" if none)."""

    sent: int
    dropped: int
    shown: int
    problem: str = ""


def check_sink(sink: Sink) -> None:
    """Raises ViewError (one line) unless the live view can go to ``sink``: the desktop viewer
    (SPAWN), a Rerun gRPC URL (CONNECT) or an ``.rrd`` file (overwritten) in an existing,
    writable directory (SAVE)."""
    match sink.kind:
        case SinkKind.CONNECT:
            grpc_address(sink.url or "", "live view URL")
        case SinkKind.SAVE:
            check_rrd_path(sink.path, "live view file")
        case SinkKind.WEB:
            raise ViewError(
                "the live view goes to the desktop viewer, a viewer's URL or an .rrd file; for a "
                "web viewer run `rerun --serve-web` and stream to its URL"
            )


def about_live(*, session_id: str, controller: str, source: str, rate_hz: float) -> str:
    """The live view's note (Markdown)."""
    run = style.hex_color(style.run_colors([RECORDED])[RECORDED])
    return "\n".join(
        [
            f"# Live: session `{session_id}`",
            "",
            f"Streamed by `hilrig record` while it records `{source}`.",
            "",
            f"**Display decimated**: every stream is shown at {rate_hz:g} Hz (the first sample"
            f" of every {1000 / rate_hz:g} ms), every event as it comes. The file holds every"
            f" sample: `hilrig view {source}` shows it after the session.",
            "",
            f"Timeline `{paths.TIMELINE}`: s from the first control tick.",
            "",
            f"- `{run}` {RECORDED} ({controller})",
            "",
            "3D: where the desired X_d (grey), the actual end from the measured joints (white)"
            f" and the controller's reference X_d + e (`{run}`) are now; the force arrow draws"
            f" {FORCE_SCALE_M_PER_N * 1000:g} mm per N.",
        ]
    )


def _groups() -> dict[str, int]:
    """``{group label: the column whose contact state the group shares}``."""
    return {label: cols[0] for label, cols in group_columns(AXIS_NAMES).items()}


class LiveLogger:
    """Logs :class:`~hilrig.rig.view_feed.ViewBatch` es to ``rec`` on the entity tree of a
    file's view, as the run ``recorded``: forces, controller quantities, contact lanes, joints,
    wrist F/T, events, and in 3D the robot, the force arrow and where each end trajectory is now
    (no whole-path lines). Carries each contact lane's last state and the last joint angles from
    batch to batch."""

    def __init__(self, rec: rr.RecordingStream, model: RobotModel) -> None:
        self.rec = rec
        self.model = model
        self.groups = _groups()
        self.contact: dict[str, int | None] = dict.fromkeys(self.groups)
        self.q_rad: FloatArray | None = None  # the last joint angles seen
        self.batches = 0

    def log(self, batch: ViewBatch) -> None:
        """Send ``batch`` (times: s from its ``t0_ns``)."""
        t0_ns, rec = batch.t0_ns, self.rec
        if len(batch.ticks):
            t_ticks = _seconds(batch.ticks, t0_ns)
            self._controller(t_ticks, batch.ticks)
            self._space(t_ticks, batch.ticks, batch.joints)
        t_ft = _seconds(batch.ft, t0_ns)
        for c, channel in enumerate(paths.WRIST_CHANNELS):
            send_scalars(rec, paths.wrist_series(channel), t_ft, _col(batch.ft, "wrench", c))
        t_joints = _seconds(batch.joints, t0_ns)
        for j in range(6):
            q_rad = _col(batch.joints, "q", j)
            send_scalars(rec, paths.joint_series(f"joint{j + 1}"), t_joints, q_rad)
        if len(batch.joints):
            self.q_rad = np.array(batch.joints["q"][-1], dtype=np.float64)
        lines = [event_line(e) for e in batch.events]
        t_events = np.array([(e.t_ns - t0_ns) / 1e9 for e in batch.events], dtype=np.float64)
        send_events(rec, t_events, [text for text, _ in lines], [lvl for _, lvl in lines])
        self.batches += 1

    def _controller(self, t_s: FloatArray, ticks: Rows) -> None:
        """Per axis the input and the controller's quantities; the contact lanes."""
        for i, axis in enumerate(AXIS_NAMES):
            send_scalars(self.rec, paths.input_series(axis), t_s, _col(ticks, "force", i))
            for quantity in paths.QUANTITIES:  # TICK_DTYPE's own field names
                path = paths.run_series(quantity, axis, RECORDED)
                send_scalars(self.rec, path, t_s, _col(ticks, quantity, i))
        for group, column in self.groups.items():
            codes = np.ascontiguousarray(ticks["contact"][:, column])
            lane = paths.contact_lane(group, RECORDED)
            self.contact[group] = send_contact(self.rec, lane, t_s, codes, self.contact[group])

    def _space(self, t_s: FloatArray, ticks: Rows, joints: Rows) -> None:
        """Where X_d and X_d + e are; the robot, its TCP and the force arrow there (m, N)."""
        rec = self.rec
        desired = np.asarray(ticks["desired_position"], dtype=np.float64)
        send_marker(rec, f"{paths.trajectory(paths.DESIRED)}/now", t_s, desired)
        reference = desired + ticks["offset"][:, :3]
        send_marker(rec, f"{paths.run_trajectory(RECORDED)}/now", t_s, reference)
        q_rad = self._joints_at(ticks["t_ns"], joints)
        if q_rad is None:
            return
        links = np.array([self.model.link_points(q) for q in q_rad])
        send_robot(rec, t_s, links)
        send_marker(rec, f"{paths.trajectory(paths.ACTUAL)}/now", t_s, links[:, -1])
        send_force(rec, t_s, links[:, -1], np.asarray(ticks["force"][:, :3], dtype=np.float64))

    def _joints_at(self, t_ns: NDArray[np.int64], joints: Rows) -> FloatArray | None:
        """The latest joint angles (N, 6) at or before each of ``t_ns``: this batch's rows, the
        previous batch's last before them (the first row before anything); None without any."""
        t_joints, q_rad = joints["t_ns"], np.asarray(joints["q"], dtype=np.float64)
        if self.q_rad is not None:
            t_joints = np.concatenate(([np.iinfo(np.int64).min], t_joints))
            q_rad = np.vstack((self.q_rad, q_rad))
        if len(t_joints) == 0:
            return None
        return np.ascontiguousarray(latest_at(t_joints, q_rad, t_ns))


def _seconds(rows: Rows, t0_ns: int) -> FloatArray:
    return (rows["t_ns"] - t0_ns).astype(np.float64) / 1e9


def _col(rows: Rows, field: str, column: int) -> FloatArray:
    return np.ascontiguousarray(rows[field][:, column], dtype=np.float64)


def event_line(record: EventRecord) -> tuple[str, str]:
    """An event's line of text (as in a file's view) and its Rerun text-log level."""
    return scene_event_line(record.kind, record.source, record.detail, record.axis, record.value)


def open_live(
    sink: Sink,
    *,
    session_id: str,
    controller: str,
    source: str,
    rate_hz: float = VIEW_RATE_HZ,
    loop_rate_hz: float = 1000.0,
    urdf: str | None = None,
) -> LiveLogger:
    """A stream to ``sink`` with the live layout, styles and note sent, and its logger.
    Raises ViewError."""
    decimation = Decimation(round(loop_rate_hz), round(rate_hz))
    rec, _ = open_stream(sink, blueprint(AXIS_NAMES, decimation), recording_id=session_id)
    color = style.run_colors([RECORDED])[RECORDED]
    run = RunStyle(RECORDED, f"{RECORDED} ({controller})", color)
    log_styles(rec, AXIS_NAMES, [run], list(_groups()))
    note = about_live(session_id=session_id, controller=controller, source=source, rate_hz=rate_hz)
    rec.log(paths.ABOUT, rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)
    return LiveLogger(rec, RobotModel(urdf))


# -- the session's end ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _LiveJob:
    """What the viewer-feed process needs, pickled into it when it is spawned."""

    sink: Sink
    session_id: str
    controller: str
    source: str
    rate_hz: float
    loop_rate_hz: float
    urdf: str | None
    queue: Queue[ViewBatch | None]
    parent_pid: int


class LiveView(LiveViewPort):
    """The session's end of a live view: the bounded queue the recorder forwards batches to
    (:attr:`queue`) and the viewer-feed process that streams them to ``sink``.

    Raises ViewError for a ``sink`` it cannot use (:func:`check_sink`); never for the viewer
    itself: what went wrong there is in the report of :meth:`stop`. Start it before the
    recorder, stop it after the recorder stopped (its last batch is then queued).
    """

    def __init__(
        self,
        sink: Sink,
        *,
        session_id: str,
        controller: str,
        source: str,
        loop_rate_hz: float = 1000.0,
        rate_hz: float = VIEW_RATE_HZ,
        urdf: str | None = None,
        queue_batches: int = QUEUE_BATCHES,
    ) -> None:
        check_sink(sink)
        self._queue: Queue[ViewBatch | None] = CONTEXT.Queue(queue_batches)
        self.rate_hz = rate_hz
        self._job = _LiveJob(
            sink,
            session_id,
            controller,
            source,
            rate_hz,
            loop_rate_hz,
            urdf,
            self._queue,
            os.getpid(),
        )
        self._child = ChildProcess("hilrig-live-view", "the live view", ViewError)
        self._problem = ""

    @property
    def queue(self) -> Queue[ViewBatch | None]:
        """Where the recorder puts its batches (bounded: a full queue drops a batch)."""
        return self._queue

    def start(self, *, timeout_s: float = START_S) -> None:
        """Spawn the viewer feed and wait until its stream is open or it gave up."""
        with _rerun_quiet():
            self._child.start(_serve, (self._job,))
        try:
            self._child.wait_report("ready", timeout_s)
        except ViewError as err:
            self._problem = str(err)

    def stop(self, counts: ViewCounts | None, *, timeout_s: float = FINISH_S) -> LiveReport:
        """End the feed (waiting up to ``timeout_s`` for its last flush) and report, with the
        recorder's ``counts`` (None if the recorder did not report)."""
        counts = counts or ViewCounts(error="the recorder did not report on the view")
        shown, problem = 0, self._problem
        if self._child.started and not problem:
            with contextlib.suppress(Exception):  # the recorder's marker may be lost
                self._queue.put_nowait(None)
            if not self._child.stop(timeout_s):
                problem = f"the live view did not finish within {timeout_s:g} s; stopped it"
            done = self._done()
            if done is not None:
                shown, problem = done[0], problem or done[1]
            elif not problem:
                problem = f"the live view exited with code {self._child.exitcode}"
        self.close()
        return LiveReport(counts.sent, counts.dropped, shown, problem or counts.error)

    def close(self) -> None:
        """Stop the feed if it still runs; release the queue (never waiting on it)."""
        self._child.close()
        self._queue.close()
        self._queue.cancel_join_thread()

    def _done(self) -> tuple[int, str] | None:
        """The feed's final report (batches shown, problem), if it sent one."""
        if not self._child.poll(0):
            return None
        try:
            done: tuple[int, str] = self._child.receive("done")
        except ViewError:
            return None
        return done


@contextlib.contextmanager
def _rerun_quiet() -> Iterator[None]:
    """Rerun's own log lines off in a process spawned here (unless RUST_LOG says otherwise):
    the feed reports a viewer problem itself, once, where Rerun would repeat it."""
    if "RUST_LOG" in os.environ:
        yield
        return
    os.environ["RUST_LOG"] = "off"
    try:
        yield
    finally:
        os.environ.pop("RUST_LOG", None)


# -- the viewer-feed process ---------------------------------------------------------------------


def _serve(conn: Connection, job: _LiveJob) -> None:
    """The viewer-feed process: open the stream, log every batch until the end marker or the
    parent's death, finish the stream and report. A problem is said once and ends the feed."""
    with contextlib.suppress(OSError):
        os.nice(NICENESS)
    try:
        _reachable(job.sink)
        live = open_live(
            job.sink,
            session_id=job.session_id,
            controller=job.controller,
            source=job.source,
            rate_hz=job.rate_hz,
            loop_rate_hz=job.loop_rate_hz,
            urdf=job.urdf,
        )
    except Exception as err:  # a viewer problem, whatever it is, must not reach the session
        report(conn, "ready")
        _give_up(conn, 0, _reason(err))
    report(conn, "ready")
    problem = _feed(job, live)
    if not problem:
        try:
            live.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            live.rec.disconnect()
        except Exception as err:
            problem = f"the viewer did not take the last data: {_reason(err)}"
    if problem:
        _give_up(conn, live.batches, problem)
    report(conn, "done", (live.batches, ""))


def _feed(job: _LiveJob, live: LiveLogger) -> str:
    """Log batches until the end marker or the parent's death; the problem that stopped it
    ("" if none)."""
    next_check = time.monotonic() + CHECK_S
    try:
        while os.getppid() == job.parent_pid:
            try:
                batch = job.queue.get(timeout=POLL_S)
            except queue.Empty:
                pass
            else:
                if batch is None:
                    return ""
                live.log(batch)
            if time.monotonic() >= next_check:  # raises if the viewer stopped taking data
                live.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
                next_check = time.monotonic() + CHECK_S
    except Exception as err:  # a viewer problem, whatever it is, must not reach the session
        return f"the viewer stopped taking data: {_reason(err)}"
    return ""


def _reachable(sink: Sink) -> None:
    """Raises ViewError if nothing listens at a CONNECT sink's address (Rerun would retry it
    for 5 s before sending anything)."""
    if sink.kind is not SinkKind.CONNECT:
        return
    url = sink.url or ""
    try:
        socket.create_connection(grpc_address(url), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as err:
        raise ViewError(f"no viewer at {url} ({err.strerror or err})") from err


def _reason(err: BaseException) -> str:
    return str(err) if isinstance(err, ViewError) else f"{type(err).__name__}: {err}"


def _give_up(conn: Connection, shown: int, problem: str) -> NoReturn:
    """Say ``problem`` once on stderr and to the session, then leave at once: Rerun would wait
    up to 5 s more for a viewer that is not there."""
    line = f"hilrig: live view: {problem}; the session goes on and records everything\n"
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(("\r\033[K" if sys.stderr.isatty() else "") + line)
        sys.stderr.flush()
    report(conn, "done", (shown, problem))
    os._exit(0)
