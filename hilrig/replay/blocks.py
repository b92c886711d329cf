"""The memory a replay writes its results into, mapped fresh and populated in the background.

A long replay writes gigabytes into fresh memory (1 h at 1 kHz x 9 axes is 1.6 GB per run),
and the page faults of that first touch cost more than the kernel itself (measured here: about
0.25 s per GB, the kernel about 0.1 s per GB). So the blocks are an anonymous mapping that a
background thread populates with ``madvise(MADV_POPULATE_WRITE)`` - a system call that runs
outside the GIL and never changes contents - while the runs already write into it: the faults
are taken on the other core. Where the call does not exist (Linux < 5.14, other systems) the
thread does nothing and the writers take the faults themselves. Blocks shared with a process
pool are not populated: there every core already writes (and faults), and populating them too
measured slower.

A process that replays one input after another (a sweep's worker) passes an :class:`Arena`:
it keeps the last private mapping and hands it out again once no array over it is alive, so
the next replay writes into memory already touched and takes no page faults at all.
"""

from __future__ import annotations

import ctypes
import mmap
import threading
import weakref
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

MADV_POPULATE_WRITE = 23  # linux/mman.h (5.14+); not exported by Python's mmap module
PAGE = 4096
CACHE_LINE = 64


@dataclass(frozen=True)
class Blocks:
    """``floats`` (A, quantities, N) float64 and ``contact`` (A, N) int8 over one anonymous
    mapping, ``shared`` with processes forked afterwards or private to this one; each
    ``floats[i, q]`` and ``contact[i]`` is one contiguous column of N values."""

    floats: NDArray[np.float64]
    contact: NDArray[np.int8]
    populating: threading.Thread | None = None

    @classmethod
    def allocate(
        cls, axes: int, quantities: int, rows: int, *, shared: bool, arena: Arena | None = None
    ) -> Blocks:
        """Map (A, quantities, rows) floats and (A, rows) contact codes; private blocks come
        from ``arena`` when one is given, and start being populated in the background when
        their memory is new."""
        # Rows are padded so that the columns the kernel writes side by side every tick start
        # one cache line apart modulo a page: at a whole number of pages apart they would all
        # fall into the same cache sets and evict each other (measured: 2-4x slower).
        float_row = _padded(rows * 8) // 8
        contact_row = _padded(rows)
        nfloat = axes * quantities * float_row * 8
        size = nfloat + axes * contact_row
        if shared:
            flags = mmap.MAP_ANONYMOUS | mmap.MAP_SHARED
            raw, new = np.frombuffer(mmap.mmap(-1, size, flags=flags), np.uint8), False
        else:
            raw, new = (arena or Arena()).take(size)
        floats = raw[:nfloat].view(np.float64)
        contact = raw[nfloat:size].view(np.int8)
        populating = None
        if new:
            populating = threading.Thread(
                target=_populate, args=(raw.ctypes.data, size), name="replay-populate"
            )
            populating.start()
        return cls(
            floats.reshape(axes, quantities, float_row)[:, :, :rows],
            contact.reshape(axes, contact_row)[:, :rows],
            populating,
        )

    def settle(self) -> None:
        """Wait for the background population (it is done long before the runs, usually)."""
        if self.populating is not None:
            self.populating.join()


class Arena:
    """One private mapping kept for the next :meth:`Blocks.allocate` in this process.

    It is handed out again only when it is large enough and no array over it is alive (every
    view of the blocks, a result table's columns among them, keeps the array it came from
    alive), so a result still in use is never written over; otherwise a new mapping replaces
    it. It holds on to the largest mapping it has made for as long as it lives.
    """

    def __init__(self) -> None:
        self._buffer: mmap.mmap | None = None
        self._handed: weakref.ref[NDArray[np.uint8]] | None = None

    def take(self, size: int) -> tuple[NDArray[np.uint8], bool]:
        """``size`` bytes over the kept mapping when it is free and large enough (False:
        touched before), else over a new one (True)."""
        free = self._handed is None or self._handed() is None
        if self._buffer is not None and free and len(self._buffer) >= size:
            new = False
        else:
            flags = mmap.MAP_ANONYMOUS | mmap.MAP_PRIVATE
            self._buffer, new = mmap.mmap(-1, size, flags=flags), True
        raw = np.frombuffer(self._buffer, np.uint8, size)
        self._handed = weakref.ref(raw)
        return raw, new


def _padded(size: int) -> int:
    """The least size >= ``size`` (bytes) that is one cache line more than a whole page."""
    return -(-max(size - CACHE_LINE, 0) // PAGE) * PAGE + CACHE_LINE


def _populate(address: int, size: int) -> None:
    try:
        madvise = ctypes.CDLL(None, use_errno=True).madvise
    except (OSError, AttributeError):
        return
    madvise.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    madvise(address, size, MADV_POPULATE_WRITE)  # EINVAL on older kernels: nothing to do
