"""What a session needs of a live view, so that the rig never imports the viewer (:mod:`hilrig.viz`
is above the rig): the CLI builds a :class:`hilrig.viz.live.LiveView`, which satisfies
:class:`LiveViewPort`, and hands it to the session."""

from __future__ import annotations

from multiprocessing.queues import Queue
from typing import Protocol

from hilrig.rig.view_feed import ViewBatch, ViewCounts


class LiveReportLike(Protocol):
    """How a live view went: batches the recorder ``sent`` and ``dropped`` (queue full),
    batches ``shown`` by the viewer feed, and the ``problem`` that ended it ("" if none)."""

    @property
    def sent(self) -> int: ...
    @property
    def dropped(self) -> int: ...
    @property
    def shown(self) -> int: ...
    @property
    def problem(self) -> str: ...


class LiveViewPort(Protocol):
    """A live view as a session drives it: :meth:`start` it before the recorder, give the
    recorder its :attr:`queue`, :meth:`stop` it after the recorder stopped (with the recorder's
    ``view_counts``), and :meth:`close` it whatever happened (idempotent)."""

    @property
    def queue(self) -> Queue[ViewBatch | None]: ...
    def start(self) -> None: ...
    def stop(self, counts: ViewCounts | None) -> LiveReportLike: ...
    def close(self) -> None: ...
