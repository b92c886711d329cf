"""Output memory for ``simulate``: the block a dropped result leaves, handed to the next call.

An hour of 9 axes is 1.07 GB of outputs. Written into fresh memory, each page is faulted in and
zeroed first; on the VMs we measure on, whose host takes back the memory the guest frees (free
page reporting), a gigabyte of fresh huge pages then costs 1-3 s where the kernel needs 0.2 s
(docs/control.md, "Output memory"). So a result's arrays are views of one block, and when the
last of them is dropped, the block comes back here; the next ``simulate`` it fits takes it,
already faulted in. CuPy's memory pool and PyTorch's caching allocator do the same.

Blocks under ``MIN_BYTES`` are left to malloc (glibc keeps those in its heap). The pool keeps at
most ``CAP_BYTES`` of dropped blocks, releasing the oldest first; ``release_memory`` empties it.
A block is only ever reused after every array made from it is gone.
"""

from __future__ import annotations

import os
import threading
import weakref
from collections import deque

import numpy as np
from numpy.typing import NDArray

MIN_BYTES = 32 << 20
CAP_BYTES = min(2 << 30, os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 8)

_lock = threading.Lock()
_free: list[NDArray[np.uint8]] = []  # dropped blocks, oldest first; only with _lock held
# Blocks whose arrays are gone, not yet in _free: a finalizer may run inside a collection while
# this thread holds _lock, so it only appends here (atomic) and sorts in if the lock is free;
# else the holder, or the next call, does.
_returned: deque[NDArray[np.uint8]] = deque()


class _Lease:
    """Owns a block while any array made from it lives (NumPy keeps it as their base)."""

    def __init__(self, block: NDArray[np.uint8], nbytes: int) -> None:
        self.__array_interface__ = {**block.__array_interface__, "shape": (nbytes,)}


def take(nbytes: int) -> NDArray[np.uint8]:
    """A writable uint8 array of ``nbytes``: a dropped block that fits, else fresh memory.

    A block fits when it holds ``nbytes`` and at most twice that; the smallest one is taken,
    the most recently dropped of equals (the likeliest to be in cache).
    """
    if nbytes < MIN_BYTES:
        return np.empty(nbytes, dtype=np.uint8)
    with _lock:
        _sort_in()
        fits = [i for i, b in enumerate(_free) if nbytes <= b.size <= 2 * nbytes]
        block = _free.pop(min(reversed(fits), key=lambda i: _free[i].size)) if fits else None
        _sort_in()
    if block is None:
        block = np.empty(nbytes, dtype=np.uint8)
    lease = _Lease(block, nbytes)
    finalizer = weakref.finalize(lease, _give_back, block)
    finalizer.atexit = False
    return np.asarray(lease)


def _give_back(block: NDArray[np.uint8]) -> None:
    _returned.append(block)
    if _lock.acquire(blocking=False):  # else its holder sorts it in before letting go
        try:
            _sort_in()
        finally:
            _lock.release()


def _sort_in() -> None:
    """Move returned blocks into the pool, then release the oldest beyond CAP_BYTES."""
    while _returned:
        _free.append(_returned.popleft())
    while sum(b.size for b in _free) > CAP_BYTES:
        del _free[0]


def _forget_in_child() -> None:
    """A forked child starts with its own lock and no blocks (the parent's may be held)."""
    global _lock
    _lock = threading.Lock()
    _free.clear()
    _returned.clear()


os.register_at_fork(after_in_child=_forget_in_child)


def release_memory() -> int:
    """Give every pooled block back to the system; returns the bytes released."""
    with _lock:
        _sort_in()
        released = sum(b.size for b in _free)
        _free.clear()
    return released
