"""Chunk contents: decompression, CRC checks and where each message is.

Reading is dominated by decompression and by moving bytes, so :func:`batches` inflates chunks on
a worker thread (zstd and zlib's CRC release the GIL) straight into a few reused buffers of a
few MiB - small enough to stay in cache while the caller gathers columns out of them.
"""

from __future__ import annotations

import contextlib
import mmap
import queue
import struct
import threading
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import numpy.typing as npt
import zstandard

from hilrig.recording.mcap_records import RECORD_HEADER, Op
from hilrig.recording.scan import ChunkInfo

_INDEX_ENTRY = np.dtype([("log", "<u8"), ("offset", "<u8")])
_MESSAGE_HEAD = struct.Struct("<HIQ")  # channel, sequence, log time (after the record header)
BATCH_BYTES = 4 << 20

#: Per channel id: log times (int64 ns) and record offsets in the decompressed chunk.
Entries = dict[int, tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]]


class ChunkError(ValueError):
    """A chunk cannot be used: unsupported compression, corrupt data or a CRC mismatch."""


_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def _self_checked(raw: bytes) -> bool:
    """True for a zstd frame that carries a content checksum, which zstd verifies itself."""
    return raw[:4] == _ZSTD_MAGIC and len(raw) > 4 and bool(raw[4] & 0x04)


def _inflate_into(
    mm: mmap.mmap,
    chunk: ChunkInfo,
    out: memoryview,
    zstd: zstandard.ZstdDecompressor,
    *,
    strict: bool = True,
) -> None:
    """Decompress ``chunk`` into ``out`` (exactly its uncompressed size) and check its CRC.

    Unless ``strict``, a zstd frame with its own content checksum (XXH64, verified while
    decompressing) stands in for the chunk's CRC32, which is then not computed again.
    """
    raw = mm[chunk.data_offset : chunk.data_offset + chunk.compressed_size]
    size = chunk.uncompressed_size
    try:
        if chunk.compression == "zstd":
            reader = zstd.stream_reader(raw)
            done = 0
            while done < size:
                got = reader.readinto(out[done:size])
                if not got:
                    break
                done += got
            if done != size or reader.read(1):
                raise ChunkError(f"does not inflate to the {size} bytes its header says")
        elif chunk.compression in ("lz4", ""):
            data = lz4.frame.decompress(raw) if chunk.compression else raw
            if len(data) != size:
                raise ChunkError(f"holds {len(data)} bytes, its header says {size}")
            out[:size] = data
        else:
            raise ChunkError(f"unsupported compression {chunk.compression!r}")
    except (zstandard.ZstdError, RuntimeError) as err:
        raise ChunkError(f"compressed data is corrupt ({err})") from err
    if not strict and chunk.compression == "zstd" and _self_checked(raw):
        return
    if chunk.uncompressed_crc and zlib.crc32(out[:size]) != chunk.uncompressed_crc:
        raise ChunkError("CRC mismatch: the chunk is corrupt")


def inflate(mm: mmap.mmap, chunk: ChunkInfo) -> bytes:
    """The chunk's records, decompressed and checked against its CRC. Raises ChunkError."""
    out = bytearray(chunk.uncompressed_size)
    _inflate_into(mm, chunk, memoryview(out), zstandard.ZstdDecompressor())
    return bytes(out)


@dataclass
class Batch:
    """Consecutive chunks decompressed back to back into ``data``; ``chunks`` gives each good
    chunk's start in ``data``, ``errors`` the chunks that could not be used."""

    data: npt.NDArray[np.uint8]
    chunks: list[tuple[ChunkInfo, int]] = field(default_factory=list)
    errors: list[tuple[ChunkInfo, ChunkError]] = field(default_factory=list)


def batches(
    mm: mmap.mmap, chunks: Sequence[ChunkInfo], *, batch_bytes: int = BATCH_BYTES
) -> Iterator[Batch]:
    """The chunks, inflated by a worker thread into batches of about ``batch_bytes``, in order.

    A batch's buffer is reused once the caller asks for the next batch.
    """
    free: queue.Queue[npt.NDArray[np.uint8]] = queue.Queue()
    for _ in range(3):
        free.put(np.empty(batch_bytes, dtype=np.uint8))
    ready: queue.Queue[Batch | BaseException | None] = queue.Queue(maxsize=2)
    stop = threading.Event()

    def work() -> None:
        zstd = zstandard.ZstdDecompressor()
        try:
            i = 0
            while i < len(chunks) and not stop.is_set():
                group = [chunks[i]]
                total = chunks[i].uncompressed_size
                i += 1
                while i < len(chunks) and total + chunks[i].uncompressed_size <= batch_bytes:
                    total += chunks[i].uncompressed_size
                    group.append(chunks[i])
                    i += 1
                buffer = free.get() if total <= batch_bytes else np.empty(total, dtype=np.uint8)
                if stop.is_set():
                    return
                batch = Batch(buffer)
                view, base = buffer.data, 0
                for chunk in group:
                    try:
                        _inflate_into(mm, chunk, view[base:], zstd, strict=False)
                        batch.chunks.append((chunk, base))
                        base += chunk.uncompressed_size
                    except ChunkError as err:
                        batch.errors.append((chunk, err))
                ready.put(batch)
            ready.put(None)
        except BaseException as err:  # handed to the consumer, which re-raises it
            ready.put(err)

    worker = threading.Thread(target=work, name="mcap-inflate", daemon=True)
    worker.start()
    try:
        while (item := ready.get()) is not None:
            if isinstance(item, BaseException):
                raise item
            yield item
            if len(item.data) == batch_bytes:
                free.put(item.data)
    finally:  # the consumer is done, perhaps early: stop the worker wherever it waits
        stop.set()
        free.put(np.empty(0, dtype=np.uint8))
        while worker.is_alive():
            with contextlib.suppress(queue.Empty):
                ready.get(timeout=0.01)


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


def scan_entries(data: bytes | memoryview) -> tuple[Entries, list[tuple[int, int]]]:
    """Message positions found by walking a chunk's records one by one (no index needed).

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
