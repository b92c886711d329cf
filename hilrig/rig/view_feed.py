"""The live view's copy: the recorder forwards a decimated copy of the rows and every event it
receives to the viewer-feed process of :mod:`hilrig.viz.live`. That copy never waits and never
costs a row of the recording."""

from __future__ import annotations

import contextlib
import queue
import threading
from dataclasses import dataclass
from multiprocessing.queues import Queue
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from hilrig.recording import EventRecord
from hilrig.rig.records import FT_DTYPE, JOINT_DTYPE, TICK_DTYPE
from hilrig.rig.rings import Rows

VIEW_RATE_HZ = 50.0  # the live view's copy: plenty for a display; the file keeps every row
VIEW_BATCH_S = 0.1  # the copy leaves in batches this far apart
VIEW_HANDOFF_S = 1.0  # at the end, the longest the last batch may take to leave the recorder


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
