"""Replay results on disk: the contract table as Parquet, or as derived topics in an MCAP file.

Parquet: ``run`` and ``law`` dictionary-encoded strings, ``t_s`` float64, the per-axis
quantities float32 (``precision="float64"`` keeps them as they are; see :mod:`.results` for the
rounding), ``contact_<axis>`` int8; every column non-nullable (no definition levels: up to twice
the writing speed), the floats but ``force_*`` byte-stream-split, all LZ4-compressed (zstd: 2-3 %
smaller, 1.4-1.8 x the time), min/max statistics for ``run``, ``law`` and ``t_s`` only; the JSON
``hilrig.runs`` and ``hilrig.input`` in the schema metadata. Row groups of
:data:`ROW_GROUP_ROWS` rows: while one is compressed and written (a background thread; pyarrow
works outside the GIL), the next is converted. :func:`load_results` reads a file back with the
table's in-memory types (float32 widened, exactly, to float64). docs/replay.md has the figures.

MCAP: one ``hilrig_msgs/msg/ControllerState`` channel per run, ``/replay/<run>/state``, where
``<run>`` is the run name with every character other than letters, digits and ``_`` replaced
by ``_`` (ROS names allow no more; ``replay.json`` maps run names to topics).
Log times are the input's own (a recording's tick times), so the file lines up with the
recording it came from when both are opened together in Foxglove or Rerun; a table input's
ticks start at the Unix epoch. The session record is the recording's (or, for a table input,
one naming the table, subject ``X00``) and ``replay.json`` is attached with the runs' metadata.

Files are written through :func:`hilrig.outputs.new_files`: an existing file is never replaced
(OutputError), and a write that fails leaves nothing behind. ``parquet_into`` and ``mcap_into``
write to a path the caller already holds (a temporary of its own ``new_files``).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from hilrig.errors import RecordingError, ReplayError
from hilrig.outputs import new_files
from hilrig.recording import (
    Attachment,
    ChannelSpec,
    ControllerSample,
    MessageType,
    SessionInfo,
    SessionWriter,
)
from hilrig.recording.session_ids import new_session_id
from hilrig.replay.results import INPUT_KEY, RUNS_KEY, run_slices, stored_float32

PathLike = str | os.PathLike[str]
PARQUET_SUFFIXES = (".parquet", ".pq")
MCAP_SUFFIXES = (".mcap",)
TABLE_SUBJECT = "X00"  # a table input has no subject; the session record needs a pseudonym
_ROS_NAME = re.compile(r"[^A-Za-z0-9_]")
#: How the per-axis quantities are stored in Parquet.
Precision = Literal["float32", "float64"]
#: Rows per Parquet row group, and per block converted while the previous one is written.
ROW_GROUP_ROWS = 1 << 20
CODEC = "lz4"  # LZ4_RAW in the file
#: Columns with min/max statistics (what a reader may filter rows by).
STATISTICS = ("run", "law", "t_s")
#: Float columns not byte-stream-split: the force's float32 mantissas are the sensor's noise
#: (split, they shrank by 6 % for twice the time).
PLAIN_FLOATS = ("force_",)


def write_parquet(table: pd.DataFrame, path: PathLike, *, precision: Precision = "float32") -> Path:
    """Write a result table (with its ``attrs`` metadata) to ``path``; returns the path.
    ``precision`` of the per-axis quantities: float32 (see the module docstring) or float64.

    Raises OutputError if the file exists or its folder cannot be written, ReplayError if the
    writing fails (nothing is left behind).
    """
    p = Path(path)
    with new_files(p) as (temporary,):
        parquet_into(table, temporary, precision=precision, shown_as=p)
    return p


def parquet_into(
    table: pd.DataFrame,
    path: Path,
    *,
    precision: Precision = "float32",
    shown_as: Path | None = None,
) -> None:
    """Write a result table to ``path`` as it is (no checks); errors name ``shown_as``."""
    shown = path if shown_as is None else shown_as
    if precision not in get_args(Precision):
        raise ReplayError(f"precision {precision!r}: known: {', '.join(get_args(Precision))}")
    narrow = precision == "float32"
    try:
        try:
            _write_parquet(table, path, _columns(table, narrow=narrow))
        except _OverflowError:  # rare: again, float64 where float32 cannot hold a value
            _write_parquet(table, path, _columns(table, narrow=narrow, wide=_too_large(table)))
    except (OSError, pa.ArrowException) as err:
        raise ReplayError(f"{shown}: cannot write Parquet: {err}") from err


@dataclass(frozen=True)
class _Column:
    """One column to write: its field, its values and how to take rows of them."""

    field: pa.Field
    values: np.ndarray
    categories: pa.Array | None = None  # a dictionary column's strings (values: its codes)

    @property
    def narrowed(self) -> bool:
        return bool(self.field.type == pa.float32() and self.values.dtype == np.float64)


class _OverflowError(Exception):
    """A value to be written as float32 is beyond its range."""


def _columns(
    table: pd.DataFrame, *, narrow: bool, wide: frozenset[str] = frozenset()
) -> list[_Column]:
    """The columns of ``table`` as they will be written (float32 where ``narrow`` allows,
    except the ``wide`` ones)."""
    out = []
    for name in map(str, table.columns):
        column = table[name]
        if isinstance(column.dtype, pd.CategoricalDtype):
            codes = np.asarray(column.cat.codes)
            strings = pa.array([str(c) for c in column.cat.categories], pa.string())
            kind = pa.dictionary(pa.from_numpy_dtype(codes.dtype), pa.string())
            out.append(_Column(pa.field(name, kind, nullable=False), codes, strings))
            continue
        values = column.to_numpy()
        if values.dtype.kind not in "biuf":
            out.append(_Column(pa.field(name, pa.array(values).type), values))
            continue
        kind = pa.from_numpy_dtype(values.dtype)
        if narrow and values.dtype == np.float64 and stored_float32(name) and name not in wide:
            kind = pa.float32()
        out.append(_Column(pa.field(name, kind, nullable=False), values))
    return out


def _too_large(table: pd.DataFrame) -> frozenset[str]:
    """The per-axis float64 columns holding a value that float32 rounds to infinity."""
    wide = set()
    with np.errstate(over="ignore"):
        for name in filter(stored_float32, map(str, table.columns)):
            values = table[name].to_numpy()
            if values.dtype == np.float64 and np.isinf(np.float32(np.abs(values).max(initial=0))):
                wide.add(name)
    return frozenset(wide)


def _write_parquet(table: pd.DataFrame, path: Path, columns: Sequence[_Column]) -> None:
    """Row group by row group: the next one is converted while a thread writes this one."""
    names = [c.field.name for c in columns]
    metadata = {key: json.dumps(table.attrs.get(key, {})) for key in (RUNS_KEY, INPUT_KEY)}
    schema = pa.schema([c.field for c in columns], metadata=metadata)
    floats = [c.field.name for c in columns if pa.types.is_floating(c.field.type)]
    split = [n for n in floats if not n.startswith(PLAIN_FLOATS)]
    dictionary = [c.field.name for c in columns if c.categories is not None]
    statistics = [n for n in STATISTICS if n in names]
    rows, narrowed = len(table), sum(c.narrowed for c in columns)
    step = min(ROW_GROUP_ROWS, max(rows, 1))
    buffers = [np.empty((narrowed, step), np.float32) for _ in range(2 if narrowed else 0)]
    writer = pq.ParquetWriter(
        path,
        schema,
        compression=CODEC,
        use_dictionary=dictionary,
        use_byte_stream_split=split or False,
        write_statistics=statistics or False,
    )
    with writer, ThreadPoolExecutor(1, thread_name_prefix="parquet-writer") as pool:
        pending: Future[None] | None = None
        for index, start in enumerate(range(0, rows, step)):
            stop = min(start + step, rows)
            block = _block(schema, columns, start, stop, buffers[index % 2] if buffers else None)
            if pending is not None:
                pending.result()  # the write before this one: the next block reuses its buffer
            pending = pool.submit(writer.write_table, block, row_group_size=stop - start)
        if pending is not None:
            pending.result()


def _block(
    schema: pa.Schema,
    columns: Sequence[_Column],
    start: int,
    stop: int,
    buffer: np.ndarray | None,
) -> pa.Table:
    """Rows ``start`` .. ``stop`` of ``columns`` (float32 ones converted into ``buffer``)."""
    arrays: list[pa.Array] = []
    narrowed = 0
    for column in columns:
        values = column.values[start:stop]
        if column.categories is not None:
            arrays.append(pa.DictionaryArray.from_arrays(pa.array(values), column.categories))
        elif column.narrowed and buffer is not None:
            out = buffer[narrowed, : stop - start]
            narrowed += 1
            try:
                with np.errstate(over="raise"):
                    np.copyto(out, values, casting="same_kind")
            except FloatingPointError:
                raise _OverflowError(column.field.name) from None
            arrays.append(pa.array(out))
        else:
            arrays.append(pa.array(values, column.field.type))
    return pa.Table.from_arrays(arrays, schema=schema)


def load_results(path: PathLike) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A result table written by :func:`write_parquet` and its runs' metadata
    (``{run name: {"law", "params", ...}}``, also in ``table.attrs``), float32 columns widened
    to float64 (the in-memory table's types).

    Raises ReplayError if the file is missing, unreadable or not a replay result.
    """
    p = Path(path)
    try:
        arrow = pq.read_table(p)
    except (OSError, pa.ArrowException) as err:
        raise ReplayError(f"{p}: cannot read Parquet: {err}") from err
    metadata = arrow.schema.metadata or {}
    if RUNS_KEY.encode() not in metadata:
        raise ReplayError(f"{p}: not a hilrig replay result (no {RUNS_KEY} metadata)")
    wide = [f.with_type(pa.float64()) if f.type == pa.float32() else f for f in arrow.schema]
    table = arrow.cast(pa.schema(wide, metadata=metadata)).to_pandas()
    for key in (RUNS_KEY, INPUT_KEY):
        table.attrs[key] = json.loads(metadata.get(key.encode(), b"{}"))
    runs: dict[str, Any] = table.attrs[RUNS_KEY]
    return table, runs


def topic_names(runs: list[str]) -> dict[str, str]:
    """``{run name: /replay/<safe name>/state}``, unique (``_2``, ``_3``.. on a clash)."""
    topics: dict[str, str] = {}
    for name in runs:
        safe = _ROS_NAME.sub("_", name)
        if not safe[:1].isalpha():
            safe = "run_" + safe
        topic, n = f"/replay/{safe}/state", 2
        while topic in topics.values():
            topic, n = f"/replay/{safe}_{n}/state", n + 1
        topics[name] = topic
    return topics


def write_mcap(
    table: pd.DataFrame,
    path: PathLike,
    *,
    session: SessionInfo | None = None,
    t0_ns: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write a result table as ``/replay/<run>/state`` topics (see the module docstring).

    ``session`` and ``t0_ns`` are the input recording's session record and first tick log
    time (:class:`.ForceTrace` has both); ``progress(done, total)`` counts ticks written.
    Raises OutputError if the file exists or its folder cannot be written, ReplayError if the
    writing fails (nothing is left behind).
    """
    p = Path(path)
    with new_files(p) as (temporary,):
        mcap_into(table, temporary, session=session, t0_ns=t0_ns, progress=progress, shown_as=p)
    return p


def mcap_into(
    table: pd.DataFrame,
    path: Path,
    *,
    session: SessionInfo | None = None,
    t0_ns: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    shown_as: Path | None = None,
) -> None:
    """:func:`write_mcap` to ``path`` as it is (no checks); errors name ``shown_as``."""
    meta = table.attrs.get(INPUT_KEY, {})
    axes = list(meta.get("axes") or _axes(table))
    runs_meta = table.attrs.get(RUNS_KEY, {})
    slices = run_slices(table)
    topics = topic_names(list(slices))
    if session is None:
        session = SessionInfo(
            session_id=new_session_id(),
            subject_id=TABLE_SUBJECT,
            rig="replay",
            controller="replay",
            start_utc_ns=0,
            start_monotonic_ns=0,
        )
    base_ns = (0 if t0_ns is None else t0_ns) - session.clock_offset_ns  # monotonic time
    channels = []
    for name, topic in topics.items():
        law = str(runs_meta.get(name, {}).get("law", ""))
        channels.append(
            ChannelSpec(topic, MessageType.CONTROLLER_STATE, names=tuple(axes), controller=law)
        )
    about = {RUNS_KEY: runs_meta, INPUT_KEY: meta, "topics": topics}
    replay_json = json.dumps(about, indent=2).encode()
    attachment = Attachment("replay.json", "application/json", replay_json)
    try:
        with SessionWriter(path, session, channels=channels, attachments=[attachment]) as writer:
            _write_runs(writer, table, axes, slices, topics, base_ns, progress)
    except RecordingError as err:
        shown = str(path if shown_as is None else shown_as)
        raise ReplayError(str(err).replace(str(path), shown)) from err


def _write_runs(
    writer: SessionWriter,
    table: pd.DataFrame,
    axes: list[str],
    slices: dict[str, slice],
    topics: dict[str, str],
    base_ns: int,
    progress: Callable[[int, int], None] | None,
) -> None:
    """Tick by tick, every run's sample of that tick (so chunks stay in time order)."""
    quantities = ("force", "offset", "velocity", "damping", "stiffness", "zeta", "contact")
    rows = {
        name: {
            q: np.stack([table[f"{q}_{a}"].to_numpy()[sl] for a in axes], axis=1)
            for q in quantities
        }
        for name, sl in slices.items()
    }
    first = next(iter(slices.values()))
    t_ns = (np.round(table["t_s"].to_numpy()[first] * 1e9).astype(np.int64) + base_ns).tolist()
    total = len(t_ns) * len(slices)
    step = 10_000
    for start in range(0, len(t_ns), step):
        stop = min(start + step, len(t_ns))
        batch = []
        for name, values in rows.items():
            force = values["force"][start:stop]
            columns = [force, values["offset"][start:stop], values["velocity"][start:stop]]
            columns += [values["damping"][start:stop], values["stiffness"][start:stop]]
            chi = np.tanh(force * force)  # what the live loop records
            columns += [chi, values["zeta"][start:stop], values["contact"][start:stop]]
            batch.append((topics[name], list(zip(*(c.tolist() for c in columns), strict=True))))
        for k in range(stop - start):
            t = t_ns[start + k]
            for topic, samples in batch:
                f, e, v, b, kk, chi, zeta, contact = samples[k]
                writer.write(topic, ControllerSample(t, f, e, v, b, kk, chi, zeta, contact))
        if progress is not None:
            progress(stop * len(slices), total)


def _axes(table: pd.DataFrame) -> list[str]:
    return [str(c)[len("offset_") :] for c in table.columns if str(c).startswith("offset_")]
