"""Fresh memory for large results, its first touch taken on another core.

A large result written into fresh memory pays for that memory's first touch: a page fault per
page, and NumPy's large allocations ask for transparent huge pages, whose faults may first
compact the machine's memory (seconds, now and then, on the slowest machine measured:
docs/control.md). :func:`fresh` maps the memory anew in small pages and has a background thread
populate it with ``madvise(MADV_POPULATE_WRITE)`` - a system call that runs outside the GIL and
never changes contents - while the caller already writes into it. Where the call does not exist
(Linux < 5.14, other systems) the thread does nothing and the writer takes the faults itself.
"""

from __future__ import annotations

import ctypes
import mmap
import threading
from typing import Any

import numpy as np
from numpy.typing import DTypeLike, NDArray

__all__ = ["MIN_BYTES", "fresh", "populating"]

MADV_POPULATE_WRITE = 23  # linux/mman.h (5.14+); not exported by Python's mmap module
MIN_BYTES = 16 << 20  # smaller results: plain np.empty (a thread costs more than it saves)


def fresh(shape: tuple[int, ...], dtype: DTypeLike) -> tuple[NDArray[Any], threading.Thread | None]:
    """An uninitialised array of ``shape`` and ``dtype`` and the thread populating it (None for
    one under MIN_BYTES, made by ``np.empty``). Join the thread before relying on the memory
    being resident; the array is usable at once either way."""
    kind = np.dtype(dtype)
    size = int(np.prod(shape)) * kind.itemsize
    if size < MIN_BYTES:
        return np.empty(shape, kind), None
    buffer = mmap.mmap(-1, size, flags=mmap.MAP_ANONYMOUS | mmap.MAP_PRIVATE)
    raw = np.frombuffer(buffer, np.uint8, size)
    return raw.view(kind).reshape(shape), populating(raw)


def populating(raw: NDArray[np.uint8]) -> threading.Thread:
    """A started thread populating the memory under ``raw`` (kept alive until it is done)."""
    thread = threading.Thread(target=_populate, args=(raw,), name="hilrig-populate", daemon=True)
    thread.start()
    return thread


def _populate(raw: NDArray[np.uint8]) -> None:
    try:
        madvise = ctypes.CDLL(None, use_errno=True).madvise
    except (OSError, AttributeError):
        return
    madvise.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    madvise(raw.ctypes.data, raw.nbytes, MADV_POPULATE_WRITE)  # EINVAL on older kernels
