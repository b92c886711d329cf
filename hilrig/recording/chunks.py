"""Chunk contents: decompression (on worker threads), CRC checks and where each message is.

Decompression dominates reading, and both zstd and zlib's CRC release the GIL, so chunks are
inflated a few at a time on a small thread pool while the caller consumes them in file order.
"""

from __future__ import annotations

import mmap
import os
import struct
import threading
import zlib
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import numpy.typing as npt
import zstandard

from hilrig.recording.mcap_records import RECORD_HEADER, Op
from hilrig.recording.scan import ChunkInfo

_INDEX_ENTRY = np.dtype([("log", "<u8"), ("offset", "<u8")])
_MESSAGE_HEAD = struct.Struct("<HIQ")  # channel, sequence, log time (after the record header)
_local = threading.local()

#: Per channel id: log times (int64 ns) and record offsets in the decompressed chunk.
Entries = dict[int, tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]]


class ChunkError(ValueError):
    """A chunk cannot be used: unsupported compression, corrupt data or a CRC mismatch."""


def inflate(mm: mmap.mmap, chunk: ChunkInfo) -> bytes:
    """The chunk's records, decompressed and checked against its CRC. Raises ChunkError."""
    raw = mm[chunk.data_offset : chunk.data_offset + chunk.compressed_size]
    try:
        if chunk.compression == "zstd":
            decompressor = getattr(_local, "zstd", None)
            if decompressor is None:
                decompressor = _local.zstd = zstandard.ZstdDecompressor()
            data = decompressor.decompress(raw, max_output_size=chunk.uncompressed_size)
        elif chunk.compression == "lz4":
            data = lz4.frame.decompress(raw)
        elif chunk.compression == "":
            data = raw
        else:
            raise ChunkError(f"unsupported compression {chunk.compression!r}")
    except (zstandard.ZstdError, RuntimeError) as err:
        raise ChunkError(f"compressed data is corrupt ({err})") from err
    if len(data) != chunk.uncompressed_size:
        raise ChunkError(f"holds {len(data)} bytes, its header says {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ChunkError("CRC mismatch: the chunk is corrupt")
    return data


def inflated(
    mm: mmap.mmap, chunks: Iterable[ChunkInfo], workers: int | None = None
) -> Iterator[tuple[ChunkInfo, bytes | ChunkError]]:
    """Each chunk with its records (or the ChunkError it raised), in order, a few in flight."""
    workers = workers or min(4, os.cpu_count() or 1)
    source = iter(chunks)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending: deque[tuple[ChunkInfo, Future[bytes]]] = deque()

        def submit() -> None:
            chunk = next(source, None)
            if chunk is not None:
                pending.append((chunk, pool.submit(inflate, mm, chunk)))

        for _ in range(2 * workers):
            submit()
        while pending:
            chunk, future = pending.popleft()
            submit()
            try:
                yield chunk, future.result()
            except ChunkError as err:
                yield chunk, err


def indexed_entries(mm: mmap.mmap, chunk: ChunkInfo) -> Entries | None:
    """Message positions from the chunk's MessageIndex records; None if absent or unusable."""
    if not chunk.message_index_offsets:
        return None
    entries: Entries = {}
    for channel_id, offset in chunk.message_index_offsets.items():
        if offset + RECORD_HEADER.size + 6 > len(mm):
            return None
        opcode, _ = RECORD_HEADER.unpack_from(mm, offset)
        found, size = struct.unpack_from("<HI", mm, offset + RECORD_HEADER.size)
        start = offset + RECORD_HEADER.size + 6
        if opcode != Op.MESSAGE_INDEX or found != channel_id or start + size > len(mm):
            return None
        pairs = np.frombuffer(mm, dtype=_INDEX_ENTRY, count=size // 16, offset=start)
        entries[channel_id] = (pairs["log"].astype(np.int64), pairs["offset"].astype(np.int64))
    return entries


def scan_entries(data: bytes) -> tuple[Entries, list[tuple[int, int]]]:
    """Message positions found by walking the chunk's records one by one (no index needed).

    Also returns ``(opcode, offset)`` of the Schema and Channel records the chunk holds.
    """
    found: dict[int, tuple[list[int], list[int]]] = {}
    definitions: list[tuple[int, int]] = []
    pos, end = 0, len(data)
    while pos + RECORD_HEADER.size <= end:
        opcode, length = RECORD_HEADER.unpack_from(data, pos)
        if opcode == Op.MESSAGE and pos + RECORD_HEADER.size + _MESSAGE_HEAD.size <= end:
            channel_id, _, log = _MESSAGE_HEAD.unpack_from(data, pos + RECORD_HEADER.size)
            times, offsets = found.setdefault(channel_id, ([], []))
            times.append(log)
            offsets.append(pos)
        elif opcode in (Op.SCHEMA, Op.CHANNEL):
            definitions.append((opcode, pos))
        pos += RECORD_HEADER.size + length
    entries = {
        cid: (np.array(t, dtype=np.int64), np.array(o, dtype=np.int64))
        for cid, (t, o) in found.items()
    }
    return entries, definitions
