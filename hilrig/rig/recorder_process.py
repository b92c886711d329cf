"""The parent's handle on the recorder process (:mod:`.recorder_child`), which writes the rows
and events of a :class:`~.recorder_feed.RecorderFeed` to MCAP.

The recorder ignores SIGINT (the loop handles Ctrl-C, then calls :meth:`RecorderProcess.stop`),
and finishes its file cleanly on :meth:`~RecorderProcess.stop`, on SIGTERM, or when the loop
process dies. Only SIGKILL leaves a truncated file, missing at most the writer's open chunk
(0.25 s): ``hilrig recover`` makes it whole.

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
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from multiprocessing.queues import Queue
from pathlib import Path
from typing import Any, NamedTuple

from hilrig.errors import RecordingError
from hilrig.recording import Attachment, SessionInfo, SplitPolicy
from hilrig.rig.recorder_child import STOP, RecorderJob, record
from hilrig.rig.recorder_feed import START_METHOD, RecorderFeed
from hilrig.rig.records import AXIS_NAMES
from hilrig.rig.view_feed import VIEW_RATE_HZ, ViewBatch, ViewCounts

POLL_S = 0.005


class RecorderSummary(NamedTuple):
    """What a stopped recorder did: ``messages`` written from the feed (``/robot_description``
    not counted) and ``drops``, the rows and events the feed refused."""

    messages: int
    drops: int


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
        self._job = RecorderJob(
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
            target=record, args=(self._job, report), name="hilrig-recorder", daemon=True
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
            self._feed.events.put(STOP, timeout=timeout_s)
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
