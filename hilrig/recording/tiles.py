"""The check that a chunk's message index tiles it, as one compiled pass (numba).

Loaded on first use (:func:`hilrig.recording.chunks.entries_of`), so that commands that only
describe a file do not load numba.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit

MESSAGE_OP = 0x05
HEAD_BYTES = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, log and publish times
RECORD_HEADER_BYTES = 1 + 8  # opcode, length


@njit(cache=True)
def _le(data: NDArray[np.uint8], at: int, size: int) -> int:
    value = 0
    for k in range(size - 1, -1, -1):
        value = (value << 8) | data[at + k]
    return value


@njit(cache=True)
def tiles(
    data: NDArray[np.uint8],
    offsets: NDArray[np.int64],
    times: NDArray[np.int64],
    starts: NDArray[np.int64],
    channels: NDArray[np.int64],
) -> bool:
    """Whether the entries are Message records of their channel with their log time, one
    after another from byte 0 to the end of ``data``. Channel ``channels[c]``'s entries are
    ``starts[c]:starts[c + 1]`` of ``offsets`` and ``times``, in file order (as an index lists
    them when log times rise with the file; otherwise the answer is False and the caller walks
    the chunk): the channels' entries are merged as the records are walked, no sort."""
    size = data.shape[0]
    count = channels.shape[0]
    cursor = starts[:-1].copy()
    expected = 0
    for _ in range(offsets.shape[0]):
        found = -1
        for c in range(count):
            if cursor[c] < starts[c + 1] and offsets[cursor[c]] == expected:
                found = c
                break
        if found < 0:
            return False
        j = cursor[found]
        cursor[found] += 1
        at = expected
        if at + HEAD_BYTES > size or data[at] != MESSAGE_OP:
            return False
        length = _le(data, at + 1, 8)
        if length >= size:
            return False
        if _le(data, at + 9, 2) != channels[found] or _le(data, at + 15, 8) != times[j]:
            return False
        expected = at + RECORD_HEADER_BYTES + length
    return bool(expected == size)
