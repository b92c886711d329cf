"""Chunk contents: decompression, CRC checks and where each message is.

Reading is dominated by decompression and by moving bytes, so :func:`batches` inflates chunks on
a worker thread (zstd and zlib's CRC release the GIL) straight into a few reused buffers of a
few MiB - small enough to stay in cache while the caller gathers columns out of them.
"""

from __future__ import annotations

import contextlib
import mmap
import queue
import threading
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace

import lz4.frame  # type: ignore[import-untyped]
import numpy as np
import numpy.typing as npt
import zstandard

from hilrig.recording.file_index import ChunkInfo
from hilrig.recording.mcap_records import Op
from hilrig.recording.parse import (
    MAX_CHUNK_BYTES,
    BadRecordError,
    kind,
    parse_message_head,
    parse_message_index,
    record_at,
)

_INDEX_ENTRY = np.dtype([("log", "<u8"), ("offset", "<u8")])
BATCH_BYTES = 4 << 20

#: Per channel id: log times (int64 ns) and record offsets in the decompressed chunk.
Entries = dict[int, tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]]


class ChunkError(ValueError):
    """A chunk cannot be used: unsupported compression, corrupt data or a CRC mismatch."""


class ChunkIndexError(ValueError):
    """A chunk's message index is damaged; the chunk itself may be sound."""


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
) -> bool:
    """Decompress ``chunk`` into ``out`` (exactly its uncompressed size) and check it.

    A zstd frame's own content checksum (XXH64, verified while decompressing) vouches for the
    data; unless ``strict`` the chunk's CRC32 is then not computed again. Returns False when
    the data is sound but the chunk's CRC field does not match it (or its header is damaged);
    raises ChunkError when the data cannot be trusted.
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
    checked = chunk.compression == "zstd" and _self_checked(raw)
    if chunk.uncompressed_crc is None:
        if not checked:
            raise ChunkError("its header is damaged and its data has no checksum of its own")
        return False
    if (checked and not strict) or not chunk.uncompressed_crc:
        return True
    if zlib.crc32(out[:size]) == chunk.uncompressed_crc:
        return True
    if checked:
        return False
    raise ChunkError("CRC mismatch: the chunk is corrupt")


def inflate(mm: mmap.mmap, chunk: ChunkInfo) -> tuple[bytes, str]:
    """The chunk's records, decompressed and checked (see :func:`_inflate_into`), and which of
    its header's fields is damaged ("" for none): a zstd frame that carries its own size and
    checksum is read whatever size field the header gives. Raises ChunkError."""
    raw = mm[chunk.data_offset : chunk.data_offset + chunk.compressed_size]
    damaged = ""
    if chunk.compression == "zstd" and _self_checked(raw):
        try:
            size = zstandard.get_frame_parameters(raw).content_size
        except zstandard.ZstdError as err:
            raise ChunkError(f"compressed data is corrupt ({err})") from err
        if 0 < size <= MAX_CHUNK_BYTES and size != chunk.uncompressed_size:
            chunk, damaged = replace(chunk, uncompressed_size=size), "size"
    out = bytearray(chunk.uncompressed_size)
    if not _inflate_into(mm, chunk, memoryview(out), zstandard.ZstdDecompressor()):
        damaged = damaged or "CRC"
    return bytes(out), damaged


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
    """Message positions from the chunk's MessageIndex records; None if it has none.

    Raises ChunkIndexError when one is damaged: not a MessageIndex of its channel, or an entry
    outside the chunk (its offset) or outside its time range.
    """
    if not chunk.message_index_offsets:
        return None
    entries: Entries = {}
    for channel_id, offset in chunk.message_index_offsets.items():
        try:
            opcode, c = record_at(mm, offset, len(mm))
            if opcode != Op.MESSAGE_INDEX:
                raise BadRecordError(f"a {kind(opcode)} is where it should be")
            found, start, count = parse_message_index(c)
        except BadRecordError as err:
            raise ChunkIndexError(f"message index record at byte {offset}: {err}") from None
        pairs = np.frombuffer(mm, dtype=_INDEX_ENTRY, count=count, offset=start)
        times, offsets = pairs["log"].astype(np.int64), pairs["offset"].astype(np.int64)
        if found != channel_id:
            problem = f"it is channel {found}'s, not channel {channel_id}'s"
        elif count and (offsets.min() < 0 or offsets.max() >= chunk.uncompressed_size):
            problem = "an entry points outside the chunk"
        elif count and (times.min() < chunk.start_ns or times.max() > chunk.end_ns):
            problem = "an entry's log time is outside the chunk's time range"
        else:
            entries[channel_id] = (times, offsets)
            continue
        raise ChunkIndexError(f"message index record at byte {offset}: {problem}")
    return entries


def entries_of(
    data: bytes | memoryview, hint: Entries | None
) -> tuple[Entries, list[tuple[int, int]], bool]:
    """Message positions in a decompressed chunk, Schema and Channel records it holds, and
    whether ``hint`` (from its message indexes) was wrong. The hint is used when its entries
    tile the chunk exactly, each a Message of its channel with its log time; else the chunk's
    records are walked. Raises ChunkError if they do not parse."""
    if hint is not None and _tiles(data, hint):
        return hint, [], False
    found, definitions = scan_entries(data)
    return found, definitions, hint is not None and not _same(found, hint)


def _tiles(data: bytes | memoryview, entries: Entries) -> bool:
    if not entries:
        return len(data) == 0
    from hilrig.recording.tiles import tiles  # numba, loaded only when chunks are read

    offsets = np.concatenate([o for _, o in entries.values()])
    times = np.concatenate([t for t, _ in entries.values()])
    starts = np.cumsum([0] + [len(o) for _, o in entries.values()], dtype=np.int64)
    channels = np.fromiter(entries, dtype=np.int64, count=len(entries))
    return bool(tiles(np.frombuffer(data, dtype=np.uint8), offsets, times, starts, channels))


def _same(a: Entries, b: Entries) -> bool:
    if set(a) != set(b):
        return False
    for cid, (times, offsets) in a.items():
        order = np.argsort(b[cid][1], kind="stable")
        if not (
            np.array_equal(offsets, b[cid][1][order]) and np.array_equal(times, b[cid][0][order])
        ):
            return False
    return True


def scan_entries(data: bytes | memoryview) -> tuple[Entries, list[tuple[int, int]]]:
    """Message positions found by walking a chunk's records one by one (no index needed).

    Also returns ``(opcode, offset)`` of the Schema and Channel records the chunk holds.
    Raises ChunkError for a record that runs past the chunk or does not belong in one.
    """
    found: dict[int, tuple[list[int], list[int]]] = {}
    definitions: list[tuple[int, int]] = []
    pos, end = 0, len(data)
    while pos < end:
        try:
            opcode, c = record_at(data, pos, end)
            if opcode == Op.MESSAGE:
                channel_id, _, log, _ = parse_message_head(c)
                times, offsets = found.setdefault(channel_id, ([], []))
                times.append(log)
                offsets.append(pos)
            elif opcode in (Op.SCHEMA, Op.CHANNEL):
                definitions.append((opcode, pos))
            else:
                raise BadRecordError(f"a {kind(opcode)} does not belong in a chunk")
        except BadRecordError as err:
            raise ChunkError(f"its record at offset {pos} is unreadable: {err}") from None
        pos = c.end
    entries = {
        cid: (np.array(t, dtype=np.int64), np.array(o, dtype=np.int64))
        for cid, (t, o) in found.items()
    }
    return entries, definitions
