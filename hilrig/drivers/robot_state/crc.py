"""zlib's CRC-32 as a compiled call, for the joint-state frames' compiled encoder (the emulated
robot's, :mod:`hilrig.emulator.frame_kernels`) and decoder (:mod:`.frames`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hilrig.compiled import njit


def _crc_table() -> NDArray[np.uint32]:
    """zlib's CRC-32 (reflected polynomial 0xEDB88320) table, one entry per byte."""
    table = np.empty(256, dtype=np.uint32)
    for n in range(256):
        c = n
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
        table[n] = c
    return table


CRC_TABLE = _crc_table()


@njit(cache=True)
def crc32(data: NDArray[np.uint8], n: int) -> int:
    """zlib.crc32 of ``data[:n]``."""
    c = np.uint32(0xFFFFFFFF)
    for i in range(n):
        c = CRC_TABLE[(c ^ data[i]) & 0xFF] ^ (c >> np.uint32(8))
    return int(c ^ np.uint32(0xFFFFFFFF))
