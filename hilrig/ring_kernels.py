"""A ring's producer side in compiled code: rows stored and published without Python per row.

The ring's header (:mod:`hilrig.rig.rings`) holds, as int64 words, the write index and the drop
count (the producer's), the producer's last look at the read index, and the read index (the
consumer's). :func:`reserve_slot` and :func:`publish` are the compiled twins of
:meth:`~hilrig.rig.rings.Ring.reserve_index` and :meth:`~hilrig.rig.rings.Ring.commit`, on the
same words, so both may serve one ring; :func:`put_rows` stores a batch of rows (the drivers'
rows of one poll) with one call.

Publication order: a row's bytes must be in memory before the write index that publishes them.
x86-64 keeps stores in program order; :func:`release_fence` keeps the compiler from moving the
row's stores after the index's (on a weakly ordered CPU it is the fence the hardware needs too).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import types
from numba.extending import intrinsic
from numpy.typing import NDArray

from hilrig.compiled import njit

# int64 words of the header: the producer's cache line (8-15), the consumer's (16-23)
WRITE_AT, DROPPED_AT, READ_SEEN_AT = 8, 9, 10
READ_AT = 16


@intrinsic
def release_fence(typingctx: Any) -> tuple[Any, Any]:
    """An LLVM ``fence release``: no store before it moves after a store after it."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        builder.fence("release")
        return context.get_dummy_value()

    return types.void(), codegen


@njit(cache=True, inline="always")
def reserve_slot(header: NDArray[np.int64], capacity: int) -> int:
    """The next free slot's index, or -1 when the ring is full (a drop, counted)."""
    write: int = header[WRITE_AT]
    if write - header[READ_SEEN_AT] >= capacity:
        header[READ_SEEN_AT] = header[READ_AT]
        if write - header[READ_SEEN_AT] >= capacity:
            header[DROPPED_AT] += 1
            return -1
    return write % capacity


@njit(cache=True, inline="always")
def publish(header: NDArray[np.int64], rows: int) -> None:
    """Make the next ``rows`` rows, stored already, the consumer's."""
    release_fence()  # type: ignore[call-arg]  # numba supplies the typing context
    header[WRITE_AT] += rows


@njit(cache=True)
def put_rows(slots: NDArray[np.void], header: NDArray[np.int64], rows: NDArray[np.void]) -> int:
    """Store and publish ``rows`` one by one, as :meth:`~hilrig.rig.rings.Ring.reserve_index`
    and :meth:`~hilrig.rig.rings.Ring.commit` do: a row the ring has no room for is a drop
    (counted). Returns the rows stored."""
    capacity = slots.shape[0]
    stored = 0
    for i in range(rows.shape[0]):
        slot = reserve_slot(header, capacity)
        if slot >= 0:
            slots[slot] = rows[i]
            publish(header, 1)
            stored += 1
    return stored
