"""The fallback: any ROS 2 CDR channel decoded message by message with ``mcap_ros2``.

Used for channels whose messages change shape (free-text events, foreign recordings). The
decoded messages are flattened into the same columns the fast path gives - dotted field paths,
``_i`` per array element, ``<path>_ns`` for times - with the dtypes of the schema where known.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from mcap.records import Schema as McapSchema
from mcap_ros2.decoder import DecoderFactory

from hilrig.recording.cdr import ColumnKind, LayoutError, layout_of
from hilrig.recording.columns import INDEX_NAME
from hilrig.recording.mcap_records import Schema
from hilrig.recording.msgdef import TIME_TYPES, parse_schema, short_name

#: (log time ns, publish time ns, sequence, serialized message)
RawMessage = tuple[int, int, int, bytes]


class DecodeError(ValueError):
    """Messages of a channel do not decode with its schema."""


def decode_frame(schema: Schema, messages: Sequence[RawMessage]) -> pd.DataFrame:
    """Decode ``messages`` (all of one channel) into a frame indexed by log time (int64 ns).

    Raises DecodeError when the schema cannot be parsed or a message does not match it.
    """
    mcap_schema = McapSchema(schema.id, schema.data, schema.encoding, schema.name)
    try:
        parse_schema(schema.name, schema.data.decode())
        with contextlib.redirect_stderr(io.StringIO()):  # the parser prints what it raises
            decoder = DecoderFactory().decoder_for("cdr", mcap_schema)
    except Exception as err:  # the vendored rosidl parser has exception types of its own
        raise DecodeError(f"schema {schema.name} cannot be parsed ({err})") from err
    if decoder is None:
        raise DecodeError(f"schema {schema.name} has encoding {schema.encoding!r}, not ros2msg")
    rows: list[dict[str, Any]] = []
    for log, publish, sequence, data in messages:
        try:
            decoded = decoder(data)
        except Exception as err:  # the decoder raises whatever its byte reader hits
            raise DecodeError(f"a message does not match schema {schema.name} ({err})") from err
        row: dict[str, Any] = {INDEX_NAME: log, "publish_time_ns": publish, "sequence": sequence}
        _flatten(decoded, "", row)
        rows.append(row)
    frame = pd.DataFrame.from_records(rows).set_index(INDEX_NAME)
    frame = frame.sort_index(kind="stable")
    return _apply_schema_dtypes(frame, schema, messages[0][3] if messages else b"")


def _flatten(value: Any, path: str, out: dict[str, Any]) -> None:
    if hasattr(value, "__slots__") and hasattr(value, "_type"):
        if value._type in TIME_TYPES:
            out[f"{path}_ns"] = value.sec * 1_000_000_000 + value.nanosec
            return
        for name in value.__slots__:
            _flatten(getattr(value, name), f"{path}.{name}" if path else name, out)
    elif isinstance(value, (list, tuple, bytes)):
        for i, item in enumerate(value):
            _flatten(item, f"{path}_{i}", out)
    else:
        out[path] = value


def _apply_schema_dtypes(frame: pd.DataFrame, schema: Schema, first: bytes) -> pd.DataFrame:
    """Give columns the dtypes of the schema (as the fast path does); strings as categories."""
    dtypes: dict[str, Any] = {"publish_time_ns": np.int64, "sequence": np.uint32}
    try:
        defs = parse_schema(schema.name, schema.data.decode())
        layout = layout_of(defs, short_name(schema.name), first)
    except (LayoutError, ValueError):
        layout = None
    for column in layout.columns if layout else ():
        if column.kind is ColumnKind.TEXT or column.name not in frame:
            continue
        if frame[column.name].isna().any():
            continue
        dtypes[column.name] = np.int64 if column.kind is ColumnKind.TIME else column.dtype
    for name in frame.columns:
        if frame[name].dtype == object or pd.api.types.is_string_dtype(frame[name]):
            dtypes[name] = "category"
    frame.index = frame.index.astype(np.int64)
    return frame.astype({k: v for k, v in dtypes.items() if k in frame.columns})
