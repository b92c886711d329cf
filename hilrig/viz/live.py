"""The live view of ``hilrig record --view``: the session in Rerun while it is recorded.

The loop does nothing for it. The recorder process, which reads every row anyway, forwards a
copy decimated to 50 Hz (:class:`~hilrig.rig.view_feed.ViewForwarder`) in batches over a
bounded queue, never waiting: a full queue drops the batch. The viewer-feed process started by
:class:`LiveView` (:mod:`.live_feed`, niced where the loop cannot run SCHED_FIFO) turns the
batches into the entity tree of a file's view (:mod:`.live_logger` on :mod:`.paths`, the
recorded controller as run ``recorded``) and streams them to the desktop viewer, a viewer or
server at a URL, or an ``.rrd`` file. A viewer that cannot be reached, or stops taking data, is
reported once; the feed then ends and the session goes on recording everything. An ``.rrd``
file must be new: it is refused before the session if it exists, written under a temporary name
beside it and moved into place at the end, whole, or not at all after a problem. A feed still
behind when the session ends shows what it can in :data:`FINISH_S` less :data:`KEEP_S`, then
keeps its file (the session up to there) and says how many batches it left unshown.

This module is the session's end: :class:`LiveView`, :func:`check_sink`, :class:`LiveReport`
(and, for callers of the single module it once was, the logger's public names).
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import os
import time
from dataclasses import dataclass
from multiprocessing.queues import Queue

from hilrig.errors import ViewError
from hilrig.outputs import check_new_file, temporary_beside
from hilrig.rerun_logs import rerun_logs_off
from hilrig.rig import VIEW_RATE_HZ, ChildProcess, LiveViewPort, ViewBatch, ViewCounts
from hilrig.rig.child import CONTEXT
from hilrig.viz.live_feed import FINISH, LiveJob, serve, unwritten
from hilrig.viz.live_logger import LiveLogger, about_live, event_line, open_live
from hilrig.viz.sinks import Sink, SinkKind, check_rrd_path, grpc_address

__all__ = [
    "LiveLogger",
    "LiveReport",
    "LiveView",
    "about_live",
    "check_sink",
    "event_line",
    "open_live",
]

QUEUE_BATCHES = 50  # 5 s of batches: a viewer stalled longer costs dropped batches
START_S = 30.0  # the feed's start-up (imports, the stream, a spawned viewer)
FINISH_S = 30.0  # the feed's last batches and flush after the session (a loaded machine is slow)
KEEP_S = 7.0  # of that, kept for the last flush and moving the file in: shown until 23 s
#: The queue's pipe holds every batch the queue admits (about 6 kB each; Linux's default pipe,
#: 64 KiB, held ten): the recorder's queue thread then never waits on a feed behind, and the
#: batches it holds are not lost when the recorder exits (19 of 351 were, beside `make test`).
PIPE_BYTES = 1 << 20


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
    (SPAWN), a Rerun gRPC URL (CONNECT) or a new ``.rrd`` file in an existing, writable
    directory (SAVE; OutputError if something is there already)."""
    match sink.kind:
        case SinkKind.CONNECT:
            grpc_address(sink.url or "", "live view URL")
        case SinkKind.SAVE:
            check_new_file(check_rrd_path(sink.path, "live view file"))
        case SinkKind.WEB:
            raise ViewError(
                "the live view goes to the desktop viewer, a viewer's URL or an .rrd file; for a "
                "web viewer run `rerun --serve-web` and stream to its URL"
            )


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
        _widen_pipe(self._queue)
        self.rate_hz = rate_hz
        keep_as = sink.path if sink.kind is SinkKind.SAVE else None
        if keep_as is not None:  # the feed writes beside it and moves it in when whole
            sink = dataclasses.replace(sink, path=temporary_beside(keep_as))
        self._job = LiveJob(
            sink,
            session_id,
            controller,
            source,
            rate_hz,
            loop_rate_hz,
            urdf,
            self._queue,
            os.getpid(),
            keep_as,
        )
        self._child = ChildProcess("hilrig-live-view", "the live view", ViewError)
        self._problem = ""

    @property
    def queue(self) -> Queue[ViewBatch | None]:
        """Where the recorder puts its batches (bounded: a full queue drops a batch)."""
        return self._queue

    def start(self, *, timeout_s: float = START_S) -> None:
        """Spawn the viewer feed and wait until its stream is open or it gave up."""
        with rerun_logs_off():
            self._child.start(serve, (self._job,))
        try:
            self._child.wait_report("ready", timeout_s)
        except ViewError as err:
            self._problem = str(err)

    def stop(self, counts: ViewCounts | None, *, timeout_s: float = FINISH_S) -> LiveReport:
        """End the feed (waiting up to ``timeout_s`` for its last batches, of which it shows those
        it can in ``timeout_s - KEEP_S``, and its flush) and report, with the recorder's
        ``counts`` (None if the recorder did not report)."""
        counts = counts or ViewCounts(error="the recorder did not report on the view")
        shown, problem, said = 0, self._problem, ""
        if self._child.started and not problem:
            budget_s = max(timeout_s - KEEP_S, 0.0)
            with contextlib.suppress(ViewError):  # gone: its exit code says why
                self._child.send((FINISH, time.monotonic() + budget_s))
            if not self._child.stop(timeout_s):
                problem = f"the live view did not finish within {timeout_s:g} s; stopped it"
            done = self._done()
            behind = False
            if done is not None:
                shown, said, behind = done
            elif not problem:
                problem = f"the live view exited with code {self._child.exitcode}"
            if not (problem or said or counts.error) and shown < counts.sent:
                why = "lost between the recorder and the feed"
                if behind:
                    why = f"still behind {budget_s:g} s after the end"
                said = f"{counts.sent - shown} batches not shown: {why}"
        self.close()
        if problem:  # the feed's own problem names its file already
            problem = unwritten(self._job, problem)
        return LiveReport(counts.sent, counts.dropped, shown, problem or said or counts.error)

    def close(self) -> None:
        """Stop the feed if it still runs; release the queue (never waiting on it); remove an
        ``.rrd`` the feed left unfinished."""
        self._child.close()
        self._queue.close()
        self._queue.cancel_join_thread()
        if self._job.keep_as is not None and self._job.sink.path is not None:
            self._job.sink.path.unlink(missing_ok=True)

    def _done(self) -> tuple[int, str, bool] | None:
        """The feed's final report (batches shown, the problem that ended it, whether its time
        ran out with batches queued), if it sent one."""
        if not self._child.poll(0):
            return None
        try:
            done: tuple[int, str, bool] = self._child.receive("done")
        except ViewError:
            return None
        return done


def _widen_pipe(batches: Queue[ViewBatch | None]) -> None:
    """Let the pipe under ``batches`` hold :data:`PIPE_BYTES`; as it was where it cannot (the
    queue's pipe is not public, another OS, a lower ``/proc/sys/fs/pipe-max-size``)."""
    writer = getattr(batches, "_writer", None)
    if writer is None or not hasattr(fcntl, "F_SETPIPE_SZ"):
        return
    with contextlib.suppress(OSError, ValueError):
        fcntl.fcntl(writer.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
