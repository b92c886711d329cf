"""The C library of this process, for the few Linux calls Python does not wrap (prctl,
mallopt)."""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import sys


@functools.cache
def linux_libc() -> ctypes.CDLL | None:
    """The C library on Linux (errno kept for ``ctypes.get_errno``); None elsewhere or when it
    cannot be found."""
    if not sys.platform.startswith("linux"):
        return None
    name = ctypes.util.find_library("c")
    return None if name is None else ctypes.CDLL(name, use_errno=True)
