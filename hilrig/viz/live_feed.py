"""The viewer-feed process of the live view: spawned by :class:`~hilrig.viz.live.LiveView`
(niced where the loop cannot run under SCHED_FIFO), it takes the recorder's batches off the
bounded queue and logs them with :class:`~hilrig.viz.live_logger.LiveLogger` until the end
marker, the end of the queue once the session said it ended (:data:`FINISH`), or its parent's
death. A feed still behind at the time the session gave it stops showing there and says so: its
file then holds the session up to that point, whole. A viewer that cannot be reached, or stops
taking data, is said once; the feed then ends and the session goes on recording everything. An
``.rrd`` file is written under a temporary name beside it and moved into place once whole (never
over a file), or removed after a problem.
"""

from __future__ import annotations

import contextlib
import os
import queue
import sys
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.queues import Queue
from pathlib import Path
from typing import NoReturn

from hilrig.errors import OutputError, ViewError
from hilrig.outputs import new_files
from hilrig.rig import ViewBatch
from hilrig.rig.child import report
from hilrig.timing import realtime_permitted
from hilrig.viz.live_logger import LiveLogger, open_live
from hilrig.viz.sinks import Sink, SinkKind, viewer_problem

POLL_S = 0.2  # the feed checks on its parent this often while no batch comes
CHECK_S = 1.0  # the stream's health (a flush) is checked this often
FLUSH_TIMEOUT_S = 5.0
CONNECT_TIMEOUT_S = 2.0
#: Where the loop cannot run under SCHED_FIFO (no root or CAP_SYS_NICE), the feed yields to it;
#: where it can, the loop preempts the feed anyway, and a niced feed starved by a busy machine
#: (``make test`` beside another) fell behind its whole session and never finished.
NICENESS = 10
#: The session's word that it ended: ``(FINISH, by_monotonic_s)``: the feed shows what is queued
#: until ``by_monotonic_s`` (CLOCK_MONOTONIC is the machine's clock, not the process's).
FINISH = "finish"


@dataclass(frozen=True)
class LiveJob:
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
    keep_as: Path | None = None  # SAVE: the file asked for (the sink's path is its temporary)


def serve(conn: Connection, job: LiveJob) -> None:
    """The viewer-feed process: open the stream, log every batch until the end marker or the
    parent's death, finish the stream and report. A problem is said once and ends the feed."""
    if not realtime_permitted():
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
        _give_up(conn, job, 0, _reason(err))
    report(conn, "ready")
    problem, behind = _feed(job, live, conn)
    if not problem:
        try:
            live.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            live.rec.disconnect()
        except Exception as err:
            problem = f"the viewer did not take the last data: {_reason(err)}"
    problem = problem or _keep(job)
    if problem:
        _give_up(conn, job, live.batches, problem)
    report(conn, "done", (live.batches, "", behind))


def _feed(job: LiveJob, live: LiveLogger, conn: Connection) -> tuple[str, bool]:
    """Log batches until the end marker, the queue's end after :data:`FINISH`, the time
    :data:`FINISH` gave, or the parent's death. Returns the problem that stopped it ("" if
    none) and whether the time ran out with batches still queued."""
    next_check = time.monotonic() + CHECK_S
    ended, finish_by_s = False, float("inf")  # until the session says it ended
    try:
        while os.getppid() == job.parent_pid:
            try:
                batch, empty = job.queue.get(timeout=POLL_S), False
            except queue.Empty:
                batch, empty = None, True
            if not ended and conn.poll():
                (_, finish_by_s), ended = conn.recv(), True
            if (batch is None and not empty) or (empty and ended):
                return "", False  # every batch queued was shown
            if time.monotonic() >= finish_by_s:  # the rest is counted by the session
                return "", True
            if batch is not None:
                live.log(batch)
            if time.monotonic() >= next_check:  # raises if the viewer stopped taking data
                live.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
                next_check = time.monotonic() + CHECK_S
    except Exception as err:  # a viewer problem, whatever it is, must not reach the session
        return f"the viewer stopped taking data: {_reason(err)}", False
    return "", False


def _reachable(sink: Sink) -> None:
    """Raises ViewError unless a Rerun viewer or server answers at a CONNECT sink's URL within
    CONNECT_TIMEOUT_S (:func:`~hilrig.viz.sinks.viewer_problem`): Rerun would retry for 5 s
    before sending anything, and wait on something that never answers."""
    if sink.kind is not SinkKind.CONNECT:
        return
    url = sink.url or ""
    problem = viewer_problem(url, CONNECT_TIMEOUT_S)
    if problem:
        raise ViewError(f"{url}: {problem}")


def _keep(job: LiveJob) -> str:
    """Move a finished ``.rrd`` into place, never over a file that appeared meanwhile; the
    problem if it cannot be ("" if moved, or nothing to move)."""
    if job.keep_as is None or job.sink.path is None:
        return ""
    try:
        with new_files(job.keep_as) as (moved,):
            os.replace(job.sink.path, moved)
    except OutputError as err:
        return str(err)
    except OSError as err:
        return f"{job.keep_as}: cannot be moved into place ({err.strerror or err})"
    return ""


def unwritten(job: LiveJob, problem: str) -> str:
    """After ``problem``, remove an unfinished ``.rrd``; ``problem`` naming the file asked for,
    not its temporary, and saying it is not written."""
    final, temporary = job.keep_as, job.sink.path
    if final is None or temporary is None:
        return problem
    temporary.unlink(missing_ok=True)
    problem = problem.replace(str(temporary), str(final))
    if problem.startswith(f"{final}:") or final.exists():  # said, or moved in after all
        return problem
    return f"{problem}; {final} not written"


def _reason(err: BaseException) -> str:
    return str(err) if isinstance(err, ViewError) else f"{type(err).__name__}: {err}"


def _give_up(conn: Connection, job: LiveJob, shown: int, problem: str) -> NoReturn:
    """Say ``problem`` once on stderr and to the session, then leave at once: Rerun would wait
    up to 5 s more for a viewer that is not there."""
    problem = unwritten(job, problem)
    line = f"hilrig: live view: {problem}; the session goes on and records everything\n"
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(("\r\033[K" if sys.stderr.isatty() else "") + line)
        sys.stderr.flush()
    report(conn, "done", (shown, problem, False))
    os._exit(0)
