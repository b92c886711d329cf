"""The loop's end of the recorder: shared-memory rings for the rows and the events.

:class:`RecorderFeed` lives in the loop process. It owns five rings: wrist F/T, joint state,
tick and servo-call rows (2 s at 1 kHz each by default) and events (fixed-size rows,
EVENT_DTYPE: no queue, no feeder thread, no pickling in the loop's process). Every call returns
at once: a full ring refuses the row or event and counts a drop (:attr:`RecorderFeed.drops`), so
a stalled, killed or missing recorder costs data, never the tick.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import TracebackType

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import RecordingError
from hilrig.recording import EventRecord
from hilrig.rig.records import (
    AXIS_BYTES,
    DETAIL_BYTES,
    EVENT_DTYPE,
    FT_DTYPE,
    JOINT_DTYPE,
    SERVO_DTYPE,
    SOURCE_BYTES,
    TICK_DTYPE,
    fitted,
)
from hilrig.rig.rings import Ring, RingSpec, Rows

RING_ROWS = 2048  # per ring: 2 s at 1 kHz
EVENT_SLOTS = 1024


class RecorderFeed:
    """The loop's end of the recorder: rings for wrist F/T, joint-state and tick rows and for
    events. Nothing here blocks, and only :meth:`event` allocates (its text's bytes).

    Per row: ``slot = feed.tick_slot()``; if it is not None fill its fields in place
    (``slot["force"] = f``, dtypes in :mod:`.records`); then ``feed.commit_tick()``, which does
    nothing when the slot was refused. The feed must be created before the recorder process and
    closed after it stopped (:meth:`close` unlinks the rings). ``rows`` per row ring and
    ``events`` bound what may wait for a recorder that has not begun yet.
    """

    def __init__(self, *, rows: int = RING_ROWS, events: int = EVENT_SLOTS) -> None:
        created: list[Ring] = []
        try:
            for label, dtype, capacity in (
                ("ft", FT_DTYPE, rows),
                ("joint", JOINT_DTYPE, rows),
                ("tick", TICK_DTYPE, rows),
                ("event", EVENT_DTYPE, events),
                ("servo", SERVO_DTYPE, rows),
            ):
                created.append(Ring.create(RingSpec.unique(label, dtype, capacity)))
        except RecordingError:
            release_rings(created)
            raise
        self.ft, self.joint, self.tick, self.events, self.servo = created

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
        """Put ``record`` for ``/events`` into its ring (texts cut to their fields, marked:
        :func:`~.records.fitted`); False (and a drop) if the ring is full."""
        return self.events.push(
            record.t_ns,
            record.value,
            record.kind,
            fitted(record.source, SOURCE_BYTES),
            fitted(record.axis, AXIS_BYTES),
            fitted(record.detail, DETAIL_BYTES),
        )

    @property
    def rings(self) -> tuple[Ring, Ring, Ring, Ring, Ring]:
        """The F/T, joint-state, tick, event and servo-call rings, in that order."""
        return self.ft, self.joint, self.tick, self.events, self.servo

    @property
    def headers(self) -> tuple[NDArray[np.int64], ...]:
        """The rings' header words (compiled code sums their drops into a tick's row)."""
        return tuple(ring.header for ring in self.rings)

    @property
    def drops(self) -> int:
        """Rows and events refused so far (every ring's drops)."""
        return sum(ring.dropped for ring in self.rings)

    def close(self) -> None:
        """Unlink and unmap the rings; what a recorder has not read by then is discarded.
        Raises RecordingError if a reserved slot is still referenced (the rings' names are gone
        by then)."""
        release_rings(self.rings)

    def __enter__(self) -> RecorderFeed:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def release_rings(rings: Sequence[Ring]) -> None:
    """Unmap each ring; its creator unlinks it first, so that a failing close cannot leave the
    name behind."""
    for ring in rings:
        if ring.owner:
            ring.unlink()
        ring.close()
