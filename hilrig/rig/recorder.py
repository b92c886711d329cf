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

Shutdown order: stop the loop, then :meth:`RecorderProcess.stop` (every row committed and every
event sent before it is recorded), then :meth:`RecorderFeed.close`.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import queue
import signal
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from pathlib import Path
from types import FrameType, TracebackType
from typing import Any, Final, NamedTuple

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


class RecorderProcess:
    """Writes the rows and events of ``feed`` to ``path`` from a separate process.

    ``session``, ``urdf``, ``attachments``, ``calibration`` and ``split`` go to the
    :class:`~hilrig.recording.SessionWriter`; ``controller`` and ``axis_names`` (the tick rows'
    axis order) label ``/controller/state``. The rings are read every ``poll_s`` seconds.
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
        )
        self._process: BaseProcess | None = None
        self._report: Connection | None = None
        self._summary: RecorderSummary | None = None

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
        self._summary = RecorderSummary(self._receive("done"), self._feed.drops)
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
        writer.close()
        _release(rings)
    _send(report, "done", messages)


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
            for messages_of, ring in (
                (ft_samples, self.ft),
                (joint_samples, self.joint),
                (tick_samples, self.tick),
            ):
                for topic, sample in messages_of(ring.read_available()):
                    self.writer.write(topic, sample)
                    written += 1
            messages += written
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
