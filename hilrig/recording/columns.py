"""The fast path: Message records of a fixed-layout channel into numpy columns, without a loop.

Inside a decompressed chunk every Message record of such a channel has the same size, so the
chunk seen through a sliding window of that size (one-byte stride, no copy) can be indexed with
the records' offsets from the MessageIndex: one fancy-indexing gather copies all of a channel's
records out of a batch of chunks. The bytes that must not change (record header, lengths,
strings) are compared with the channel's first record, as integers through strided views, then
each run of same-typed values is copied, transposed, into preallocated columns. Batches are
small enough to stay in cache, and each step is one numpy call per batch, not per message.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from hilrig.recording.cdr import ColumnKind, Layout
from hilrig.recording.mcap_records import MESSAGE_PREFIX

INDEX_NAME = "log_time_ns"
_PREFIX = MESSAGE_PREFIX.size
_HEAD = (0, 11)  # opcode, record length and channel id: equal in every record of the channel
_SEC, _NANOSEC = ".sec", ".nanosec"  # the halves of a time, joined in FixedChannel.frame
_WIDENED = ("log", "publish_time_ns")  # uint64 on disk, int64 ns (like the index) in frames


@dataclass(frozen=True)
class _Strided:
    """``count`` values of ``dtype`` starting at record byte ``offset``, ``step`` bytes apart:
    a run of columns to copy, or a group of fixed bytes to compare."""

    offset: int
    dtype: np.dtype[np.generic]
    count: int
    step: int

    def view(self, rows: npt.NDArray[np.void], record_size: int) -> npt.NDArray[np.generic]:
        """The values in every row, shape (rows, count), without copying."""
        return np.ndarray(
            (len(rows), self.count),
            self.dtype,
            buffer=rows,
            offset=self.offset,
            strides=(record_size, self.step),
        )


def _grouped(items: list[tuple[int, np.dtype[np.generic]]], *, dense: bool) -> list[_Strided]:
    """Consecutive values of one dtype at a constant step, as runs; ``dense`` allows only the
    item size as step (a run of columns must be contiguous to keep the columns in order)."""
    groups: list[_Strided] = []
    for offset, dtype in items:
        last = groups[-1] if groups else None
        if last is not None and dtype == last.dtype:
            step = offset - last.offset if last.count == 1 else last.step
            regular = step > 0 and offset == last.offset + last.count * step
            if regular and (not dense or step == dtype.itemsize):
                groups[-1] = _Strided(last.offset, dtype, last.count + 1, step)
                continue
        groups.append(_Strided(offset, dtype, 1, dtype.itemsize))
    return groups


def _pieces(start: int, end: int) -> list[tuple[int, np.dtype[np.generic]]]:
    """Bytes ``[start, end)`` as unsigned integers of 8, 4, 2 and 1 bytes: comparing integers
    is several times faster than comparing byte strings."""
    pieces: list[tuple[int, np.dtype[np.generic]]] = []
    for size in (8, 4, 2, 1):
        while end - start >= size:
            pieces.append((start, np.dtype(f"<u{size}")))
            start += size
    return pieces


def _fixed_ranges(layout: Layout) -> list[tuple[int, int]]:
    merged: list[tuple[int, int]] = []
    for start, end in sorted([_HEAD, *((_PREFIX + a, _PREFIX + b) for a, b in layout.fixed)]):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(end, merged[-1][1]))
        else:
            merged.append((start, end))
    return merged


def _value_items(layout: Layout) -> tuple[list[tuple[int, np.dtype[np.generic]]], list[str]]:
    """Every value to copy (record offset, dtype) and its column name, in record order."""
    items: list[tuple[int, np.dtype[np.generic]]] = [
        (11, np.dtype("<u4")),
        (15, np.dtype("<u8")),
        (23, np.dtype("<u8")),
    ]
    names = ["sequence", "log", "publish_time_ns"]
    for column in layout.columns:
        offset = _PREFIX + column.offset
        if column.kind is ColumnKind.TIME:
            items += [(offset, np.dtype("<i4")), (offset + 4, np.dtype("<u4"))]
            names += [column.name + _SEC, column.name + _NANOSEC]
        elif column.kind is ColumnKind.VALUE:
            items.append((offset, np.dtype(column.dtype)))
            names.append(column.name)
    return items, names


class FixedChannel:
    """Columns of one fixed-layout channel, filled batch by batch.

    ``reference`` is the channel's first Message record; every later record must match its
    size and fixed bytes, else :meth:`gather` refuses it (the channel then takes the slow path).
    """

    def __init__(self, layout: Layout, reference: bytes, capacity: int) -> None:
        self.layout = layout
        self.record_size = len(reference)
        pieces = [p for a, b in _fixed_ranges(layout) for p in _pieces(a, b)]
        self._checks = _grouped(pieces, dense=False)
        row = np.frombuffer(reference, dtype=np.dtype((np.void, self.record_size)))
        self._expected = [check.view(row, self.record_size)[0].copy() for check in self._checks]
        items, self._names = _value_items(layout)
        self._runs = _grouped(items, dense=True)
        self._columns: list[npt.NDArray[np.generic]] = []
        first = 0  # index in self._names of each run's first column
        for run in self._runs:
            dtype = np.dtype(np.int64) if self._names[first] in _WIDENED else run.dtype
            self._columns.append(np.empty((run.count, capacity), dtype))
            first += run.count
        self.filled = 0

    def gather(self, data: npt.NDArray[np.uint8], offsets: npt.NDArray[np.int64]) -> bool:
        """Append the records at ``offsets`` in ``data``; False if any does not fit the layout."""
        size, n = self.record_size, len(offsets)
        if n == 0:
            return True
        if offsets.min() < 0 or offsets.max() + size > len(data):
            return False
        windows = np.ndarray(
            (len(data) - size + 1,), dtype=np.dtype((np.void, size)), buffer=data, strides=(1,)
        )
        rows = windows[offsets]
        for check, expected in zip(self._checks, self._expected, strict=True):
            if not (check.view(rows, size) == expected).all():
                return False
        self._reserve(self.filled + n)
        start, stop = self.filled, self.filled + n
        for run, column in zip(self._runs, self._columns, strict=True):
            column[:, start:stop] = run.view(rows, size).T
        self.filled = stop
        return True

    def _reserve(self, rows: int) -> None:
        capacity = self._columns[0].shape[1]
        if rows <= capacity:
            return
        grown = max(rows, 2 * capacity)
        for i, column in enumerate(self._columns):
            bigger = np.empty((column.shape[0], grown), column.dtype)
            bigger[:, : self.filled] = column[:, : self.filled]
            self._columns[i] = bigger

    def frame(self) -> pd.DataFrame:
        """One column per field, indexed by log time (int64 ns), rows in log-time order.

        Also ``publish_time_ns`` (int64) and ``sequence`` (uint32) from the Message records;
        strings are categoricals with their one value.
        """
        n = self.filled
        flat = [values for column in self._columns for values in column[:, :n]]
        data: dict[str, npt.NDArray[np.generic]] = dict(zip(self._names, flat, strict=True))
        log = data.pop("log").astype(np.int64, copy=False)
        if n > 1 and bool((log[1:] < log[:-1]).any()):
            order = np.argsort(log, kind="stable")
            log = log[order]
            data = {k: v[order] for k, v in data.items()}
        ordered: dict[str, object] = {
            "publish_time_ns": data["publish_time_ns"],
            "sequence": data["sequence"],
        }
        for column in self.layout.columns:
            if column.kind is ColumnKind.TEXT:
                ordered[column.name] = pd.Categorical.from_codes(
                    np.zeros(n, dtype=np.int8), categories=pd.Index([column.text])
                )
            elif column.kind is ColumnKind.TIME:
                sec = data[column.name + _SEC].astype(np.int64)
                nanosec = data[column.name + _NANOSEC].astype(np.int64)
                ordered[column.name] = sec * 1_000_000_000 + nanosec
            else:
                ordered[column.name] = data[column.name]
        return pd.DataFrame(ordered, index=pd.Index(log, name=INDEX_NAME), copy=False)
