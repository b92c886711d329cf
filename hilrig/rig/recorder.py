"""The recorder: the loop's rows go through shared-memory rings to a process that writes MCAP.

:class:`RecorderFeed` lives in the loop process. It owns three rings (wrist F/T, joint state,
tick rows; 2 s at 1 kHz each by default) and a bounded queue for events, the only variable-size
records. Every call returns at once: a full ring or queue refuses the row or event and counts a
drop (:attr:`RecorderFeed.drops`), so a stalled, killed or missing recorder costs data, never
the tick.

:class:`RecorderProcess` runs the consumer in a separate process: every ``poll_s`` it copies out
what the rings hold, turns the rows into samples (:func:`ft_samples` ...) and writes them with
:class:`~hilrig.recording.SessionWriter`. It ignores SIGINT (the loop handles Ctrl-C, then calls
:meth:`RecorderProcess.stop`), and finishes its file cleanly on :meth:`~RecorderProcess.stop`,
on SIGTERM, or when the loop process dies. Only SIGKILL leaves a truncated file, missing at
most the writer's open chunk (0.25 s): ``hilrig recover`` makes it whole.

With a live view (``hilrig record --view``), the recorder also forwards a decimated copy of what
it receives (:class:`ViewForwarder`) to the viewer-feed process of :mod:`hilrig.viz.live`; that
copy never waits and never costs a row of the recording.

Shutdown order: stop the loop, then :meth:`RecorderProcess.stop` (every row committed and every
event sent before it is recorded), then :meth:`RecorderFeed.close`.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import queue
import signal
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from pathlib import Path
from types import FrameType, TracebackType
from typing import Any, Final, NamedTuple

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import HilrigError, RecordingError
from hilrig.recording import (
    Attachment,
    ControllerSample,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    SessionInfo,
    SessionWriter,
    SplitPolicy,
    WrenchSample,
    default_channels,
)
from hilrig.rig.records import AXIS_NAMES, FT_DTYPE, JOINT_DTYPE, TICK_DTYPE
from hilrig.rig.rings import Ring, RingSpec, Rows

# "spawn": the loop process runs driver threads, and forking a threaded process can copy a lock
# held by another thread into the child. "forkserver" would be as safe, but its children are
# the fork server's, not the loop's: the recorder could not watch its parent's pid.
START_METHOD: Final = "spawn"
RING_ROWS = 2048  # per ring: 2 s at 1 kHz
EVENT_SLOTS = 1024
POLL_S = 0.005
IDLE_FLUSH_S = 0.25  # hand a quiet writer's open chunk to the OS after this long without data
VIEW_RATE_HZ = 50.0  # the live view's copy: plenty for a display; the file keeps every row
VIEW_BATCH_S = 0.1  # the copy leaves in batches this far apart
VIEW_HANDOFF_S = 1.0  # at the end, the longest the last batch may take to leave the recorder
_STOP = None  # the last item stop() puts on the event queue


class RecorderFeed:
    """The loop's end of the recorder: rings for wrist F/T, joint-state and tick rows, a queue
    for events. Nothing here blocks, and only :meth:`event` allocates.

    Per row: ``slot = feed.tick_slot()``; if it is not None fill its fields in place
    (``slot["force"] = f``, dtypes in :mod:`.records`); then ``feed.commit_tick()``, which does
    nothing when the slot was refused. The feed must be created before the recorder process and
    closed after it stopped (:meth:`close` unlinks the rings).
    """

    def __init__(self, *, rows: int = RING_ROWS, events: int = EVENT_SLOTS) -> None:
        created: list[Ring] = []
        try:
            for label, dtype in (("ft", FT_DTYPE), ("joint", JOINT_DTYPE), ("tick", TICK_DTYPE)):
                created.append(Ring.create(RingSpec.unique(label, dtype, rows)))
        except RecordingError:
            _release(created)
            raise
        self.ft, self.joint, self.tick = created
        self.events: Queue[EventRecord | None] = multiprocessing.get_context(START_METHOD).Queue(
            events
        )
        self.event_drops = 0

    def ft_slot(self) -> Rows | None:
        """The next wrist F/T row (FT_DTYPE) to fill, or None if its ring is full (a drop)."""
        return self.ft.reserve()

    def commit_ft(self) -> None:
        """Publish the F/T row returned by :meth:`ft_slot` (nothing if it returned None)."""
        self.ft.commit()

    def joint_slot(self) -> Rows | None:
        """The next joint-state row (JOINT_DTYPE) to fill, or None if its ring is full."""
        return self.joint.reserve()

    def commit_joint(self) -> None:
        """Publish the row returned by :meth:`joint_slot` (nothing if it returned None)."""
        self.joint.commit()

    def tick_slot(self) -> Rows | None:
        """The next tick row (TICK_DTYPE) to fill, or None if its ring is full."""
        return self.tick.reserve()

    def commit_tick(self) -> None:
        """Publish the row returned by :meth:`tick_slot` (nothing if it returned None)."""
        self.tick.commit()

    def event(self, record: EventRecord) -> bool:
        """Queue ``record`` for ``/events``; False (and a drop) if the queue is full. The
        queue's feeder thread pickles it; the first call starts that thread."""
        try:
            self.events.put_nowait(record)
        except queue.Full:
            self.event_drops += 1
            return False
        return True

    @property
    def drops(self) -> int:
        """Rows and events refused so far (every ring's drops plus the event queue's)."""
        return self.ft.dropped + self.joint.dropped + self.tick.dropped + self.event_drops

    def close(self) -> None:
        """Unlink and unmap the rings and close the event queue; events not yet taken by a
        recorder are discarded. Raises RecordingError if a reserved slot is still referenced
        (the rings' names are gone by then)."""
        self.events.close()
        self.events.cancel_join_thread()  # never wait at exit for a recorder that is gone
        _release([self.ft, self.joint, self.tick])

    def __enter__(self) -> RecorderFeed:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class RecorderSummary(NamedTuple):
    """What a stopped recorder did: ``messages`` written from the feed (``/robot_description``
    not counted) and ``drops``, the rows and events the feed refused."""

    messages: int
    drops: int


@dataclass(frozen=True)
class _Job:
    """Everything the recorder process needs, pickled into it when it is spawned."""

    path: Path
    session: SessionInfo
    rings: tuple[RingSpec, RingSpec, RingSpec]  # ft, joint, tick
    events: Queue[EventRecord | None]
    parent_pid: int
    controller: str
    axis_names: tuple[str, ...]
    urdf: str | None
    attachments: tuple[Attachment, ...]
    calibration: Mapping[str, object] | None
    split: SplitPolicy | None
    poll_s: float
    view: Queue[ViewBatch | None] | None
    view_rate_hz: float


class RecorderProcess:
    """Writes the rows and events of ``feed`` to ``path`` from a separate process.

    ``session``, ``urdf``, ``attachments``, ``calibration`` and ``split`` go to the
    :class:`~hilrig.recording.SessionWriter`; ``controller`` and ``axis_names`` (the tick rows'
    axis order) label ``/controller/state``. The rings are read every ``poll_s`` seconds.
    ``view`` is the live view's queue: a copy decimated to ``view_rate_hz`` goes there
    (:class:`ViewForwarder`); :attr:`view_counts` says how that went once stopped.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        session: SessionInfo,
        *,
        feed: RecorderFeed,
        urdf: str | None = None,
        attachments: Sequence[Attachment] = (),
        calibration: Mapping[str, object] | None = None,
        controller: str = "adaptive",
        axis_names: tuple[str, ...] = AXIS_NAMES,
        split: SplitPolicy | None = None,
        poll_s: float = POLL_S,
        view: Queue[ViewBatch | None] | None = None,
        view_rate_hz: float = VIEW_RATE_HZ,
    ) -> None:
        self.path = Path(path)
        self._feed = feed
        self._context = multiprocessing.get_context(START_METHOD)
        self._job = _Job(
            path=self.path,
            session=session,
            rings=(feed.ft.spec, feed.joint.spec, feed.tick.spec),
            events=feed.events,
            parent_pid=os.getpid(),
            controller=controller,
            axis_names=axis_names,
            urdf=urdf,
            attachments=tuple(attachments),
            calibration=calibration,
            split=split,
            poll_s=poll_s,
            view=view,
            view_rate_hz=view_rate_hz,
        )
        self._process: BaseProcess | None = None
        self._report: Connection | None = None
        self._summary: RecorderSummary | None = None
        self.view_counts: ViewCounts | None = None  # set by stop() when there is a view

    @property
    def pid(self) -> int | None:
        """The recorder process's pid (None before :meth:`start`)."""
        return None if self._process is None else self._process.pid

    def start(self, *, timeout_s: float = 60.0) -> None:
        """Spawn the recorder and return once its file is open.

        Raises RecordingError if it was started before, cannot create the file, or is not
        ready within ``timeout_s`` (a spawned process imports hilrig first: about 1 s).
        """
        if self._process is not None:
            raise RecordingError(f"recorder of {self.path}: already started")
        self._report, report = self._context.Pipe(duplex=False)
        process = self._context.Process(
            target=_record, args=(self._job, report), name="hilrig-recorder", daemon=True
        )
        # SIGINT is blocked across the spawn: a Ctrl-C while the child starts up stays pending
        # (the mask is inherited) until the child ignores it.
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        self._process = process
        report.close()  # the child's end: EOF here once the child is gone
        if not self._report.poll(timeout_s):
            self.kill()
            raise RecordingError(f"recorder of {self.path}: not ready within {timeout_s} s")
        self._receive("ready")

    def stop(self, *, timeout_s: float = 10.0) -> RecorderSummary:
        """Record everything committed and sent so far, finish the file and wait for the process.
        Calling it again returns the same summary.

        Raises RecordingError if the recorder was not started, failed, died, or did not finish
        within ``timeout_s`` (it is then killed; ``hilrig recover`` repairs its file).
        """
        if self._summary is not None:
            return self._summary
        process = self._started()
        deadline = time.monotonic() + timeout_s
        # The marker follows every event sent before; a stalled recorder's full queue refuses
        # it, and the join below then times out.
        with contextlib.suppress(queue.Full):
            self._feed.events.put(_STOP, timeout=timeout_s)
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            self.kill()
            raise RecordingError(
                f"recorder of {self.path}: not finished within {timeout_s} s; killed it"
            )
        messages, self.view_counts = self._receive("done")
        self._summary = RecorderSummary(messages, self._feed.drops)
        return self._summary

    def kill(self) -> None:
        """SIGKILL the recorder and reap it (its file is left as it was: truncated)."""
        process = self._started()
        process.kill()
        process.join()

    def _started(self) -> BaseProcess:
        if self._process is None:
            raise RecordingError(f"recorder of {self.path}: not started")
        return self._process

    def _receive(self, kind: str) -> Any:
        """The value of the recorder's next report, which should be ``kind``. Raises
        RecordingError with the recorder's own error, or with how it ended if it sent none."""
        assert self._report is not None  # made by start()
        try:
            got, value = self._report.recv()
        except EOFError:
            process = self._started()
            process.join()
            raise RecordingError(
                f"recorder of {self.path}: exited with code {process.exitcode} before reporting"
                f" {kind}"
            ) from None
        if got == "error":
            self._started().join()  # it exits right after saying so
            raise RecordingError(f"recorder of {self.path}: {value}")
        return value


# -- rows to samples ----------------------------------------------------------------------------

FT_TOPIC = "/ft/wrist"
JOINT_TOPIC = "/joint_states"
INPUT_TOPIC = "/controller/input"
STATE_TOPIC = "/controller/state"
DESIRED_TOPIC = "/trajectory/desired"
COMMANDED_TOPIC = "/trajectory/commanded"
LOOP_TOPIC = "/diagnostics/loop"
EVENTS_TOPIC = "/events"

Messages = Iterator[tuple[str, Sample]]


def ft_samples(rows: Rows) -> Messages:
    """``/ft/wrist`` samples of FT_DTYPE rows (sensor frame, N and N*m). The driver's frame
    counter goes to ``device_seq``, which the writer keeps only on device-clock channels."""
    for t_ns, seq, w in zip(
        rows["t_ns"].tolist(), rows["seq"].tolist(), rows["wrench"].tolist(), strict=True
    ):
        yield FT_TOPIC, WrenchSample(t_ns, (w[0], w[1], w[2]), (w[3], w[4], w[5]), device_seq=seq)


def joint_samples(rows: Rows) -> Messages:
    """``/joint_states`` samples of JOINT_DTYPE rows, stamped with the robot's time and sequence."""
    columns = ("t_ns", "q", "qd", "tau", "device_t_ns", "seq")
    for t_ns, q, qd, tau, device_t_ns, seq in zip(
        *(rows[c].tolist() for c in columns), strict=True
    ):
        yield JOINT_TOPIC, JointSample(t_ns, q, qd, tau, device_t_ns=device_t_ns, device_seq=seq)


_TICK_COLUMNS = (
    "t_ns",
    "force",
    "moment",
    "offset",
    "offset_rate",
    "damping",
    "stiffness",
    "chi",
    "zeta",
    "contact",
    "desired_position",
    "desired_orientation",
    "commanded_q",
    "tick",
    "period_ns",
    "compute_ns",
    "lateness_ns",
    "overruns",
    "queue_drops",
)


def tick_samples(rows: Rows) -> Messages:
    """Per TICK_DTYPE row, in this order: ``/controller/input`` (the compensated wrist wrench
    in the base frame, N and N*m), ``/controller/state`` (all axes), ``/trajectory/desired``,
    ``/trajectory/commanded`` (positions only) and ``/diagnostics/loop``."""
    columns = zip(*(rows[c].tolist() for c in _TICK_COLUMNS), strict=True)
    for t, f, m, e, ed, b, k, chi, zeta, contact, p, o, q, *timing in columns:
        yield INPUT_TOPIC, WrenchSample(t, (f[0], f[1], f[2]), (m[0], m[1], m[2]))
        yield STATE_TOPIC, ControllerSample(t, f, e, ed, b, k, chi, zeta, contact)
        yield DESIRED_TOPIC, PoseSample(t, (p[0], p[1], p[2]), (o[0], o[1], o[2], o[3]))
        yield COMMANDED_TOPIC, JointSample(t, q)
        yield LOOP_TOPIC, LoopTiming(t, *timing)


# -- the live view's copy -----------------------------------------------------------------------


@dataclass(frozen=True)
class ViewBatch:
    """A decimated copy of rows the recorder received (wrist F/T, joint state and tick rows, in
    the dtypes of :mod:`.records`) and every event, for the live view. ``t0_ns`` is the
    session's first control tick: the view's time zero."""

    t0_ns: int
    ft: Rows
    joints: Rows
    ticks: Rows
    events: tuple[EventRecord, ...]


class ViewCounts(NamedTuple):
    """What the recorder did for a live view: batches ``sent`` and ``dropped`` (the queue was
    full), and ``error``, why forwarding stopped ("" if it never did)."""

    sent: int = 0
    dropped: int = 0
    error: str = ""


def first_per_period(
    t_ns: NDArray[np.int64], period_ns: int, previous: int = -1
) -> tuple[NDArray[np.intp], int]:
    """Indices of the rows of ascending ``t_ns`` that are the first of their period
    (``t_ns // period_ns``), ``previous`` being the period of the row seen before them (-1:
    none); and the period of the last row, to pass on with the next rows."""
    period = t_ns // period_ns
    keep = np.flatnonzero(np.diff(period, prepend=previous) != 0)
    return keep, int(period[-1]) if len(period) else previous


_VIEW_STREAMS = {"ft": FT_DTYPE, "joints": JOINT_DTYPE, "ticks": TICK_DTYPE}


class ViewForwarder:
    """The recorder's copy for the live view: per stream, the first row of every
    ``1 / rate_hz`` s, and every event, put on ``queue`` as a :class:`ViewBatch` every
    ``batch_s`` from the first tick on. Nothing here waits: a full queue drops the batch
    (counted), and the first failure stops forwarding (kept in ``error``), never the recording.
    """

    def __init__(self, queue: Queue[ViewBatch | None], *, rate_hz: float, batch_s: float) -> None:
        self.queue = queue
        self.period_ns = round(1e9 / rate_hz)
        self.batch_ns = round(batch_s * 1e9)
        self.rows: dict[str, list[Rows]] = {stream: [] for stream in _VIEW_STREAMS}
        self.last_period = dict.fromkeys(_VIEW_STREAMS, -1)
        self.events: list[EventRecord] = []
        self.t0_ns: int | None = None
        self.due_ns = 0
        self.sent = self.dropped = 0
        self.error = ""

    def rows_read(self, stream: str, rows: Rows) -> None:
        """Keep the rows of ``stream`` ("ft", "joints" or "ticks") due for the view."""
        if self.error or len(rows) == 0:
            return
        try:
            t_ns = rows["t_ns"]
            keep, self.last_period[stream] = first_per_period(
                t_ns, self.period_ns, self.last_period[stream]
            )
            self.rows[stream].append(rows[keep])
            if stream == "ticks" and self.t0_ns is None:
                self.t0_ns = int(t_ns[0])
        except Exception as err:  # the view must never cost the recording
            self._fail(err)

    def event(self, record: EventRecord) -> None:
        if not self.error:
            self.events.append(record)

    def send_due(self, now_ns: int) -> None:
        """Send what was kept if ``batch_s`` has passed since the last batch."""
        if now_ns >= self.due_ns:
            self.due_ns = now_ns + self.batch_ns
            self._send()

    def finish(self, timeout_s: float) -> ViewCounts:
        """Send what is left and the end marker, and give the queue up to ``timeout_s`` to hand
        them over: a viewer feed that stopped reading cannot keep the recorder from exiting."""
        self._send()
        try:
            with contextlib.suppress(queue.Full):  # then the feed's parent ends it
                self.queue.put_nowait(None)
            self.queue.close()
            handover = threading.Thread(target=self.queue.join_thread, daemon=True)
            handover.start()
            handover.join(timeout_s)
            if handover.is_alive():
                self.queue.cancel_join_thread()
        except Exception as err:  # the view must never cost the recording
            self.error = self.error or f"{type(err).__name__}: {err}"
        return ViewCounts(self.sent, self.dropped, self.error)

    def _send(self) -> None:
        if self.error or self.t0_ns is None:  # times count from the first tick
            return
        try:
            ft, joints, ticks = (_joined(self.rows[s], dtype) for s, dtype in _VIEW_STREAMS.items())
            batch = ViewBatch(self.t0_ns, ft, joints, ticks, tuple(self.events))
            for kept in self.rows.values():
                kept.clear()
            self.events.clear()
            if not (len(ft) or len(joints) or len(ticks) or batch.events):
                return
            self.queue.put_nowait(batch)  # pickled by the queue's thread, not here
            self.sent += 1
        except queue.Full:
            self.dropped += 1
        except Exception as err:  # the view must never cost the recording
            self._fail(err)

    def _fail(self, err: Exception) -> None:
        self.error = f"{type(err).__name__}: {err}"
        for kept in self.rows.values():
            kept.clear()
        self.events.clear()


def _joined(parts: list[Rows], dtype: np.dtype[Any]) -> Rows:
    return np.concatenate(parts) if parts else np.empty(0, dtype=dtype)


# -- the recorder process -----------------------------------------------------------------------


def _record(job: _Job, report: Connection) -> None:
    """The recorder process: open the file, report ready, write until told to stop, report."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the loop's; it then calls stop()
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked by start()
    rings: list[Ring] = []
    try:
        for spec in job.rings:
            rings.append(Ring.attach(spec))
        writer = SessionWriter(
            job.path,
            job.session,
            channels=default_channels(axis_names=job.axis_names, controller=job.controller),
            calibration=job.calibration,
            attachments=job.attachments,
            urdf=job.urdf,
            split=job.split,
        )
    except HilrigError as err:
        _release(rings)
        _send(report, "error", str(err))
        return
    recorder = _Recorder(job, writer, rings)
    signal.signal(signal.SIGTERM, recorder.on_sigterm)
    _send(report, "ready", None)
    try:
        messages = recorder.run()
    except HilrigError as err:
        _send(report, "error", str(err))
        return
    finally:
        try:
            writer.close()
            _release(rings)
        finally:  # the file is closed: now the live view's last batch may take its time
            views = None if recorder.view is None else recorder.view.finish(VIEW_HANDOFF_S)
    _send(report, "done", (messages, views))


def _send(report: Connection, kind: str, value: object) -> None:
    """Tell the parent how things went (it may be gone: then nobody needs to know)."""
    with contextlib.suppress(OSError):
        report.send((kind, value))


class _Recorder:
    """The recorder process's loop over the rings and the event queue."""

    def __init__(self, job: _Job, writer: SessionWriter, rings: list[Ring]) -> None:
        self.job, self.writer = job, writer
        self.ft, self.joint, self.tick = rings
        self.terminated = False
        self.view = None
        if job.view is not None:
            self.view = ViewForwarder(job.view, rate_hz=job.view_rate_hz, batch_s=VIEW_BATCH_S)

    def on_sigterm(self, signum: int, frame: FrameType | None) -> None:
        """SIGTERM (also multiprocessing's at the parent's exit) finishes the file cleanly."""
        self.terminated = True

    def run(self) -> int:
        """Write what arrives every ``poll_s`` until the stop marker, SIGTERM or the parent's
        death; returns the number of messages written."""
        messages = 0
        last_data = time.monotonic()
        dirty = False  # the writer holds data since the last flush
        while True:
            # Checked before the drain: a dead loop's last rows are then all in the rings.
            finishing = self.terminated or os.getppid() != self.job.parent_pid
            written, stopping = self.drain_events()
            # Rows are read after the events: all rows committed before stop() are in the rings.
            for messages_of, ring, stream in (
                (ft_samples, self.ft, "ft"),
                (joint_samples, self.joint, "joints"),
                (tick_samples, self.tick, "ticks"),
            ):
                rows = ring.read_available()
                for topic, sample in messages_of(rows):
                    self.writer.write(topic, sample)
                    written += 1
                if self.view is not None:
                    self.view.rows_read(stream, rows)
            messages += written
            if self.view is not None:
                self.view.send_due(time.monotonic_ns())
            now = time.monotonic()
            if written:
                last_data, dirty = now, True
            elif dirty and now - last_data >= IDLE_FLUSH_S:
                self.writer.flush()  # a paused loop's last rows reach the disk too
                dirty = False
            if stopping or finishing:
                return messages

    def drain_events(self) -> tuple[int, bool]:
        """Write queued events, waiting up to ``poll_s`` for the first (the loop's sleep).
        Returns how many were written and whether the stop marker came."""
        events = self.job.events
        written = 0
        try:
            item = events.get(timeout=self.job.poll_s)
            while item is not _STOP:
                self.writer.write(EVENTS_TOPIC, item)
                written += 1
                if self.view is not None:
                    self.view.event(item)
                item = events.get_nowait()
        except queue.Empty:
            return written, False
        return written, True


def _release(rings: Sequence[Ring]) -> None:
    """Unmap each ring; its creator unlinks it first, so that a failing close cannot leave the
    name behind."""
    for ring in rings:
        if ring.owner:
            ring.unlink()
        ring.close()
