"""The parent's handle on the recorder process (:mod:`.recorder_child`), which writes the rows
and events of a :class:`~.recorder_feed.RecorderFeed` to MCAP.

It starts in two steps, so that a session can spawn it early (its imports take about 1 s) while
the rig comes up: :meth:`RecorderProcess.spawn` returns at once, the child attaches the rings
and waits; :meth:`~RecorderProcess.begin` hands it the session and calibration, and
:meth:`~RecorderProcess.ready` says once its file is open. Until ``begin`` nothing reads the
rings: the rows committed meanwhile wait there (up to ``RecorderFeed(rows=...)`` per ring).

The recorder ignores SIGINT (the loop handles Ctrl-C, then calls :meth:`RecorderProcess.stop`),
and finishes its file cleanly on :meth:`~RecorderProcess.stop`, on SIGTERM, or when the loop
process dies. Only SIGKILL leaves a truncated file, missing at most the writer's open chunk
(0.25 s): ``hilrig recover`` makes it whole. A write its disk refuses (full, failing) leaves the
same file, cut at its last whole chunk: the recorder then reports it and exits, and
:meth:`RecorderProcess.failure` says so (the session's watchdog asks when it exits).

Shutdown order: stop the loop, then :meth:`RecorderProcess.stop` (every row and event committed
before it is recorded), then :meth:`RecorderFeed.close`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from multiprocessing.queues import Queue
from pathlib import Path
from typing import Any, NamedTuple

from hilrig.errors import RecordingError
from hilrig.recording import Attachment, SessionInfo, SessionOutcome, SplitPolicy
from hilrig.rig.child import ChildProcess
from hilrig.rig.recorder_child import BEGIN, FAILED, STOP, RecorderJob, record
from hilrig.rig.recorder_feed import RecorderFeed
from hilrig.rig.records import AXIS_NAMES
from hilrig.rig.view_feed import VIEW_RATE_HZ, ViewBatch, ViewCounts
from hilrig.rig.write_failure import WriteFailure

POLL_S = 0.005


class RecorderSummary(NamedTuple):
    """What a stopped recorder did: ``messages`` written from the feed (``/robot_description``
    not counted) and ``drops``, the rows and events the feed refused."""

    messages: int
    drops: int


class RecorderProcess:
    """Writes the rows and events of ``feed`` to ``path`` from a separate process.

    ``urdf``, ``attachments`` and ``split`` go to the :class:`~hilrig.recording.SessionWriter`;
    ``controller`` and ``axis_names`` (the tick rows' axis order) label ``/controller/state``.
    The rings are read every ``poll_s`` seconds once begun. ``view`` is the live view's queue:
    a copy decimated to ``view_rate_hz`` goes there (:class:`~.view_feed.ViewForwarder`);
    :attr:`view_counts` says how that went once stopped.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        feed: RecorderFeed,
        urdf: str | None = None,
        attachments: Sequence[Attachment] = (),
        controller: str = "adaptive",
        axis_names: tuple[str, ...] = AXIS_NAMES,
        split: SplitPolicy | None = None,
        poll_s: float = POLL_S,
        view: Queue[ViewBatch | None] | None = None,
        view_rate_hz: float = VIEW_RATE_HZ,
    ) -> None:
        self.path = Path(path)
        self._feed = feed
        self._job = RecorderJob(
            path=self.path,
            rings=tuple(ring.spec for ring in feed.rings),  # type: ignore[arg-type]
            parent_pid=os.getpid(),
            controller=controller,
            axis_names=axis_names,
            urdf=urdf,
            attachments=tuple(attachments),
            split=split,
            poll_s=poll_s,
            view=view,
            view_rate_hz=view_rate_hz,
        )
        self._child = ChildProcess("hilrig-recorder", f"recorder of {self.path}", RecordingError)
        self._begun = self._ready = False
        self._summary: RecorderSummary | None = None
        self._report: tuple[str, Any] | None = None  # read by failure(), not yet handled
        self._failure: WriteFailure | None = None
        self.view_counts: ViewCounts | None = None  # set by stop() when there is a view

    @property
    def pid(self) -> int | None:
        """The recorder process's pid (None before :meth:`spawn`)."""
        return self._child.pid

    def spawn(self) -> None:
        """Start the recorder process and return at once; it attaches the rings and waits for
        :meth:`begin`. Raises RecordingError if it was spawned before."""
        self._child.start(record, (self._job,))

    def begin(self, session: SessionInfo, calibration: Mapping[str, object] | None) -> None:
        """Hand the spawned recorder its session and calibration (returns at once): it opens
        the file and starts reading the rings. Raises RecordingError if it was not spawned,
        began before, or is gone."""
        if self._begun:
            raise RecordingError(f"recorder of {self.path}: already begun")
        self._child.send((BEGIN, session, calibration))
        self._begun = True

    def ready(self, timeout_s: float = 0.0) -> bool:
        """Whether the file is open (waiting up to ``timeout_s`` for it). Raises RecordingError
        with the recorder's own error (e.g. the file exists), or its exit code if it died."""
        if not self._ready and self._child.poll(timeout_s):
            self._child.receive("ready")
            self._ready = True
        return self._ready

    def start(
        self,
        session: SessionInfo,
        calibration: Mapping[str, object] | None = None,
        *,
        timeout_s: float = 60.0,
    ) -> None:
        """:meth:`spawn`, :meth:`begin`, and wait until the file is open. Raises RecordingError
        as those do, or if not ready within ``timeout_s`` (it is then killed)."""
        self.spawn()
        self.begin(session, calibration)
        if not self.ready(timeout_s):
            self.kill()
            raise RecordingError(f"recorder of {self.path}: not ready within {timeout_s:g} s")

    def alive(self) -> bool:
        """The recorder process runs: one ``waitpid(WNOHANG)`` system call, no I/O."""
        return self._child.alive()

    def failure(self) -> WriteFailure | None:
        """The write a disk refused, if the recorder (begun and ready) reported one: its file
        is then sealed and it exits. No waiting: a report not yet sent is not seen."""
        if self._failure is None and self._report is None and self._ready and self._child.poll():
            self._report = self._child.next_report()
            if self._report[0] == FAILED:
                self._failure = self._report[1]
        return self._failure

    @property
    def sentinel(self) -> int:
        """A file descriptor that becomes readable when the recorder process ends."""
        return self._child.sentinel

    def stop(
        self, *, outcome: SessionOutcome | None = None, timeout_s: float = 10.0
    ) -> RecorderSummary:
        """Record everything committed and sent so far, and ``outcome`` (the session's end
        figures) as the file's last metadata record; finish the file and wait for the process
        (a recorder that never began exits without a file: 0 messages). Calling it again returns
        the same summary.

        Raises RecordingError if the recorder was not spawned, failed (a disk's refusal:
        :meth:`failure`), died, or did not finish within ``timeout_s`` (it is then killed;
        ``hilrig recover`` repairs its file).
        """
        if self._summary is not None:
            return self._summary
        if not self._child.started:
            raise RecordingError(f"recorder of {self.path}: not started")
        # every row and event committed before is in the rings, which the recorder reads once
        # more after this message
        if not self._child.stop(timeout_s, message=(STOP, outcome)):
            raise RecordingError(
                f"recorder of {self.path}: not finished within {timeout_s:g} s; killed it"
            )
        if self._begun and not self._ready:
            self.ready()  # raises the recorder's error if it never opened its file
        messages, self.view_counts = self._done()
        self._summary = RecorderSummary(messages, self._feed.drops)
        return self._summary

    def _done(self) -> Any:
        """The value of the recorder's ``done`` report; RecordingError for any other end."""
        report = self._report or self._child.next_report()
        if report[0] == FAILED:
            self._failure = report[1]
            raise RecordingError(f"recorder of {self.path}: {self._failure.problem}")
        return self._child.expect(report, "done")

    def kill(self) -> None:
        """SIGKILL the recorder and reap it (its file is left as it was: truncated)."""
        if not self._child.started:
            raise RecordingError(f"recorder of {self.path}: not started")
        self._child.kill()
