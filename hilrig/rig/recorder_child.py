"""The recorder process: every ``poll_s`` it copies out what the rings hold, turns the rows
into samples (:mod:`.row_messages`) and writes them with :class:`~hilrig.recording.SessionWriter`;
with a live view it also forwards a decimated copy (:class:`~.view_feed.ViewForwarder`). Between
polls it waits on its pipe to the parent, which says when to stop and with what outcome.

A write the disk refuses (full, over quota, failing: :mod:`.write_failure`) ends it at once: the
file is cut back to its last whole chunk (``SessionWriter.seal``), the rings are released and
it reports ``("failed", WriteFailure)`` instead of ``done``, then exits."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Mapping
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.queues import Queue
from pathlib import Path
from types import FrameType

from hilrig.errors import HilrigError
from hilrig.recording import (
    Attachment,
    SessionInfo,
    SessionOutcome,
    SessionWriter,
    SplitPolicy,
    default_channels,
)
from hilrig.rig.child import report
from hilrig.rig.recorder_feed import release_rings
from hilrig.rig.rings import Ring, RingSpec
from hilrig.rig.row_messages import (
    event_samples,
    ft_samples,
    joint_samples,
    servo_samples,
    tick_samples,
)
from hilrig.rig.view_feed import VIEW_BATCH_S, VIEW_HANDOFF_S, ViewBatch, ViewForwarder
from hilrig.rig.write_failure import WriteFailure, write_failure
from hilrig.timing import freeze_heap

#: Ahead of a busy machine's other work (where permitted: root or CAP_SYS_NICE), behind the loop's
#: and the rig's SCHED_FIFO threads: a recorder starved by other processes holds rows in the
#: rings and its unflushed chunk, which a crash would lose. Not SCHED_FIFO: its chunk writes must
#: not keep the kernel's workers (the tty's, which hand the loop its F/T frames) waiting.
RECORDER_NICENESS = -10
IDLE_FLUSH_S = 0.25  # hand a quiet writer's open chunk to the OS after this long without data
BEGIN = "begin"  # RecorderProcess.begin() sends (BEGIN, session, calibration)
STOP = "stop"  # RecorderProcess.stop() sends (STOP, outcome or None)
FAILED = "failed"  # the recorder reports (FAILED, WriteFailure): a disk refused a write


@dataclass(frozen=True)
class RecorderJob:
    """What the recorder process needs from the start, pickled into it when it is spawned."""

    path: Path
    # ft, joint, tick, events, servo
    rings: tuple[RingSpec, RingSpec, RingSpec, RingSpec, RingSpec]
    parent_pid: int
    controller: str
    axis_names: tuple[str, ...]
    urdf: str | None
    attachments: tuple[Attachment, ...]
    split: SplitPolicy | None
    poll_s: float
    view: Queue[ViewBatch | None] | None
    view_rate_hz: float


def record(conn: Connection, job: RecorderJob) -> None:
    """The recorder process: attach the rings, wait for ``("begin", session, calibration)``
    (anything else, or the parent's end, ends it: ``done`` with nothing written), open the file,
    report ready, write until told to stop, report done."""
    with contextlib.suppress(OSError):  # not permitted: normal priority
        os.setpriority(os.PRIO_PROCESS, 0, RECORDER_NICENESS)
    rings: list[Ring] = []
    try:
        for spec in job.rings:
            rings.append(Ring.attach(spec))
        begin = _begin(conn)
        if begin is None:
            release_rings(rings)
            report(conn, "done", (0, None))
            return
        session, calibration = begin
        writer = SessionWriter(
            job.path,
            session,
            channels=default_channels(axis_names=job.axis_names, controller=job.controller),
            calibration=calibration,
            attachments=job.attachments,
            urdf=job.urdf,
            split=job.split,
        )
    except (HilrigError, OSError) as err:
        release_rings(rings)
        report(conn, "error", _opening_error(err, job.path))
        return
    recorder = _Recorder(job, conn, writer, rings)
    signal.signal(signal.SIGTERM, recorder.on_sigterm)
    freeze_heap()  # the collector's passes then walk only what the session makes
    report(conn, "ready")
    try:
        messages = recorder.run()
    except HilrigError as err:
        report(conn, "error", str(err))
        return
    finally:
        try:
            recorder.close()
            release_rings(rings)
        finally:  # the file is closed: now the live view's last batch may take its time
            views = None if recorder.view is None else recorder.view.finish(VIEW_HANDOFF_S)
    if recorder.failure is not None:
        report(conn, FAILED, recorder.failure)
    else:
        report(conn, "done", (messages, views))


def _opening_error(err: HilrigError | OSError, path: Path) -> str:
    """The recorder's error when its file cannot be opened: a disk's refusal (the file, begun
    by this writer, removed), else ``err``'s own (an OSError of another kind is raised)."""
    if isinstance(err, HilrigError):
        return str(err)
    failure = write_failure(err, path, 0)
    if failure is None:
        raise err
    path.unlink(missing_ok=True)  # "xb": the writer made it, and it holds no sample
    return f"{failure.problem}: the recording could not start, nothing kept; {failure.remedy}"


def _begin(conn: Connection) -> tuple[SessionInfo, Mapping[str, object] | None] | None:
    """The session and calibration of the parent's ``begin``; None if it stops first or is
    gone."""
    try:
        message = conn.recv()
    except (EOFError, OSError):
        return None
    if isinstance(message, tuple) and message[0] == BEGIN:
        return message[1], message[2]
    return None


class _Recorder:
    """The recorder process's loop over the rings."""

    def __init__(
        self, job: RecorderJob, conn: Connection, writer: SessionWriter, rings: list[Ring]
    ) -> None:
        self.job, self.conn, self.writer = job, conn, writer
        self.ft, self.joint, self.tick, self.events, self.servo = rings
        self.terminated = False
        self.outcome: SessionOutcome | None = None  # the session's end figures, with the stop
        self.failure: WriteFailure | None = None  # the write a disk refused: the file is sealed
        self.messages = 0
        self.view = None
        if job.view is not None:
            self.view = ViewForwarder(job.view, rate_hz=job.view_rate_hz, batch_s=VIEW_BATCH_S)

    def on_sigterm(self, signum: int, frame: FrameType | None) -> None:
        """SIGTERM (also multiprocessing's at the parent's exit) finishes the file cleanly."""
        self.terminated = True

    def run(self) -> int:
        """Write what arrives every ``poll_s`` until the parent's stop, SIGTERM, the parent's
        death or a write the disk refuses (:attr:`failure`); returns the number of messages
        written."""
        try:
            self._run()
        except OSError as err:  # its frames, with their views of the rings, are gone here
            self._failed(err)
        return self.messages

    def close(self) -> None:
        """Finish the file with the parent's outcome (if it came), or seal it if the disk
        refuses that."""
        outcome = self.outcome
        try:
            self.writer.close(None if outcome is None else outcome.to_metadata())
        except OSError as err:
            self._failed(err)

    def _failed(self, err: OSError) -> None:
        """Seal the file after ``err``, a disk's refusal (:attr:`failure`); re-raise another."""
        failure = write_failure(err, self.job.path, self.writer.kept_until_ns)
        if failure is None:
            raise err
        self.writer.seal()
        self.failure = failure

    def _run(self) -> None:
        last_data = time.monotonic()
        dirty = False  # the writer holds data since the last flush
        while True:
            # Checked before the rings are read: a dead loop's last rows are then all in them.
            finishing = self.terminated or os.getppid() != self.job.parent_pid
            # Rings are read after the stop: all committed before stop() are in them by then.
            stopping = self.stop_came()
            written = self.write_events()
            for messages_of, ring, stream in (
                (ft_samples, self.ft, "ft"),
                (joint_samples, self.joint, "joints"),
                (tick_samples, self.tick, "ticks"),
                (servo_samples, self.servo, ""),  # not shown live
            ):
                rows = ring.read_available()
                for topic, sample in messages_of(rows):
                    self.writer.write(topic, sample)
                    written += 1
                if self.view is not None and stream:
                    self.view.rows_read(stream, rows)
            self.messages += written
            if self.view is not None:
                self.view.send_due(time.monotonic_ns())
            now = time.monotonic()
            if written:
                last_data, dirty = now, True
            elif dirty and now - last_data >= IDLE_FLUSH_S:
                self.writer.flush()  # a paused loop's last rows reach the disk too
                dirty = False
            if stopping or finishing:
                return

    def write_events(self) -> int:
        """Write (and forward to the live view) the events in their ring; returns how many."""
        written = 0
        for topic, record in event_samples(self.events.read_available()):
            self.writer.write(topic, record)
            if self.view is not None:
                self.view.event(record)
            written += 1
        return written

    def stop_came(self) -> bool:
        """Wait up to ``poll_s`` (the loop's sleep) for the parent's stop, keeping its outcome.
        True once it came, or once the parent is gone (EOF: finish the file)."""
        try:
            if not self.conn.poll(self.job.poll_s):
                return False
            message = self.conn.recv()
        except (EOFError, OSError):
            return True
        if isinstance(message, tuple) and message[0] == STOP:
            self.outcome = message[1]
            return True
        return False
