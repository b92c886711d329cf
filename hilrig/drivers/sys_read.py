"""read(2) from compiled code: a link's bytes received by the same call that decodes them.

numba calls the C library's ``read`` and ``__errno_location`` by their symbol names
(``types.ExternalFunction``; the process has them loaded, and the kernels stay cacheable), so a
decoder's kernel can take a link's waiting bytes straight into its buffer without returning to
Python for the system call (:meth:`~hilrig.drivers.compiled_decoder.CompiledDecoder.receive`).
Linux only, as the drivers' links are (a pty, non-blocking sockets).

The result of the last read goes into ``io[LAST_READ]`` (the byte count, or ``-errno``), and the
bytes taken are added to ``io[BYTES_READ]``; :func:`read_error` turns a result into what the
driver does with it.
"""

from __future__ import annotations

import errno
import os
from typing import Any

import numpy as np
from numba import types
from numba.np.numpy_support import carray
from numpy.typing import NDArray

from hilrig.compiled import njit

BYTES_READ, LAST_READ = 0, 1  # entries of a decoder's io array
IO_WORDS = 2
# Results of a read that mean "nothing now": a non-blocking descriptor with nothing waiting, or
# a signal that came first (Python retries those too).
NOTHING_NOW = frozenset({-errno.EAGAIN, -errno.EWOULDBLOCK, -errno.EINTR})

_read: Any = types.ExternalFunction("read", types.intp(types.intc, types.voidptr, types.uintp))
_errno_location: Any = types.ExternalFunction(
    "__errno_location",
    types.CPointer(types.intc)(),  # type: ignore[no-untyped-call]
)


@njit(cache=True, inline="always")
def read_into(
    fd: int, buffer: NDArray[np.uint8], start: int, size: int, io: NDArray[np.int64]
) -> int:
    """``read(fd, buffer[start:], size)``: the bytes read (0 at the end of a stream, or from an
    empty tty set for timeout 0), or ``-errno``; also into ``io[LAST_READ]``, and the bytes added
    to ``io[BYTES_READ]``."""
    count: int = _read(fd, buffer[start:].ctypes.data, size)
    if count < 0:
        count = -carray(_errno_location(), (1,))[0]
    else:
        io[BYTES_READ] += count
    io[LAST_READ] = count
    return count


def read_error(result: int) -> OSError | None:
    """The error of a read's ``result`` (``-errno``) to raise, or None (bytes, the end of a
    stream, or nothing waiting now)."""
    if result >= 0 or result in NOTHING_NOW:
        return None
    return OSError(-result, os.strerror(-result))
