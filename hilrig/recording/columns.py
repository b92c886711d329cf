"""The fast path: Message records of a fixed-layout channel as numpy columns, without a loop.

Inside a decompressed chunk every Message record of such a channel has the same size, so the
chunk seen through a sliding window of that size (one-byte stride, no copy) can be indexed with
the records' offsets from the chunk's MessageIndex: one fancy-indexing gather copies all of a
channel's records out of the chunk. A structured dtype over those rows then yields every field
as a column (:mod:`.cdr` knows where each value sits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from hilrig.recording.cdr import ColumnKind, Layout
from hilrig.recording.mcap_records import MESSAGE_PREFIX, Op

INDEX_NAME = "log_time_ns"
_PREFIX = MESSAGE_PREFIX.size
#: Fields of the Message record prefix, by byte offset in the record.
_RECORD_FIELDS = {"op": ("u1", 0), "length": ("<u8", 1), "channel": ("<u2", 9)}
_TIME_FIELDS = {"sequence": ("<u4", 11), "log": ("<u8", 15), "publish": ("<u8", 23)}

Rows = npt.NDArray[np.void]


@dataclass(frozen=True)
class FixedChannel:
    """A channel read through its fixed layout: ``record_size`` = Message record bytes."""

    channel_id: int
    layout: Layout

    @property
    def record_size(self) -> int:
        return _PREFIX + self.layout.size

    def gather(self, chunk: bytes, offsets: npt.NDArray[np.int64]) -> Rows | None:
        """Copy the records at ``offsets`` out of ``chunk`` as rows of ``record_size`` bytes.

        Returns None when any of them is not a Message record of this channel and size (the
        channel then has no fixed layout after all).
        """
        size = self.record_size
        if len(offsets) == 0:
            return np.empty(0, dtype=np.dtype((np.void, size)))
        if offsets.min() < 0 or offsets.max() + size > len(chunk):
            return None
        windows = np.ndarray(
            shape=(len(chunk) - size + 1,),
            dtype=np.dtype((np.void, size)),
            buffer=chunk,
            strides=(1,),
        )
        rows: Rows = windows[offsets]
        head = rows.view(_dtype(size, _RECORD_FIELDS))
        ok = (
            (head["op"] == Op.MESSAGE).all()
            and (head["length"] == size - 9).all()
            and (head["channel"] == self.channel_id).all()
        )
        return rows if ok else None

    def consistent(self, rows: Rows) -> bool:
        """True when the layout's fixed bytes (lengths, strings) are the same in every row."""
        if len(rows) == 0:
            return True
        raw = rows.view(np.uint8).reshape(len(rows), self.record_size)
        return all(
            bool((raw[:, _PREFIX + a : _PREFIX + b] == raw[0, _PREFIX + a : _PREFIX + b]).all())
            for a, b in self.layout.fixed
        )

    def frame(self, rows: Rows) -> pd.DataFrame:
        """One column per field, indexed by log time (int64 ns), rows in log-time order.

        Adds ``publish_time_ns`` (int64) and ``sequence`` (uint32) from the Message records.
        """
        size = self.record_size
        fields = dict(_TIME_FIELDS)
        for column in self.layout.columns:
            if column.kind is ColumnKind.VALUE:
                fields[column.name] = (column.dtype, _PREFIX + column.offset)
            elif column.kind is ColumnKind.TIME:
                fields[column.name + ".sec"] = ("<i4", _PREFIX + column.offset)
                fields[column.name + ".nanosec"] = ("<u4", _PREFIX + column.offset + 4)
        view = rows.view(_dtype(size, fields))
        log = view["log"].astype(np.int64)
        if len(log) > 1 and bool((log[1:] < log[:-1]).any()):
            order = np.argsort(log, kind="stable")
            view, log = view[order], log[order]
        n = len(view)
        data: dict[str, object] = {
            "publish_time_ns": view["publish"].astype(np.int64),
            "sequence": np.ascontiguousarray(view["sequence"]),
        }
        for column in self.layout.columns:
            if column.kind is ColumnKind.VALUE:
                data[column.name] = np.ascontiguousarray(view[column.name])
            elif column.kind is ColumnKind.TIME:
                sec = view[column.name + ".sec"].astype(np.int64)
                data[column.name] = sec * 1_000_000_000 + view[column.name + ".nanosec"]
            else:
                data[column.name] = pd.Categorical.from_codes(
                    np.zeros(n, dtype=np.int8), categories=pd.Index([column.text])
                )
        return pd.DataFrame(data, index=pd.Index(log, name=INDEX_NAME), copy=False)


def _dtype(size: int, fields: dict[str, tuple[str, int]]) -> np.dtype[np.void]:
    return np.dtype(
        {
            "names": list(fields),
            "formats": [f for f, _ in fields.values()],
            "offsets": [o for _, o in fields.values()],
            "itemsize": size,
        }
    )
