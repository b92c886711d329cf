"""Replay results on disk: the contract table as Parquet, or as derived topics in an MCAP file.

Parquet: the table's columns as they are (``run`` and ``law`` dictionary-encoded strings, the
rest float64 and int8), zstd-compressed, with the JSON ``hilrig.runs`` and ``hilrig.input`` in
the schema metadata; :func:`load_results` reads it back.

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
from collections.abc import Callable
from pathlib import Path
from typing import Any

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
from hilrig.replay.results import INPUT_KEY, RUNS_KEY, run_slices

PathLike = str | os.PathLike[str]
PARQUET_SUFFIXES = (".parquet", ".pq")
MCAP_SUFFIXES = (".mcap",)
TABLE_SUBJECT = "X00"  # a table input has no subject; the session record needs a pseudonym
_ROS_NAME = re.compile(r"[^A-Za-z0-9_]")


def write_parquet(table: pd.DataFrame, path: PathLike) -> Path:
    """Write a result table (with its ``attrs`` metadata) to ``path``; returns the path.

    Raises OutputError if the file exists or its folder cannot be written, ReplayError if the
    writing fails (nothing is left behind).
    """
    p = Path(path)
    with new_files(p) as (temporary,):
        parquet_into(table, temporary, shown_as=p)
    return p


def parquet_into(table: pd.DataFrame, path: Path, *, shown_as: Path | None = None) -> None:
    """Write a result table to ``path`` as it is (no checks); errors name ``shown_as``."""
    shown = path if shown_as is None else shown_as
    arrays: list[pa.Array] = []
    for name in table.columns:
        column = table[name]
        if isinstance(column.dtype, pd.CategoricalDtype):
            codes = pa.array(np.asarray(column.cat.codes))
            categories = pa.array([str(c) for c in column.cat.categories], pa.string())
            arrays.append(pa.DictionaryArray.from_arrays(codes, categories))
        else:
            arrays.append(pa.array(column.to_numpy()))
    metadata = {key: json.dumps(table.attrs.get(key, {})) for key in (RUNS_KEY, INPUT_KEY)}
    arrow = pa.Table.from_arrays(arrays, names=[str(c) for c in table.columns], metadata=metadata)
    try:
        pq.write_table(
            arrow, path, compression="zstd", compression_level=1, use_dictionary=["run", "law"]
        )
    except (OSError, pa.ArrowException) as err:
        raise ReplayError(f"{shown}: cannot write Parquet: {err}") from err


def load_results(path: PathLike) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A result table written by :func:`write_parquet` and its runs' metadata
    (``{run name: {"law", "params", ...}}``, also in ``table.attrs``).

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
    table = arrow.to_pandas()
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
        stem = Path(str(meta.get("source", "table"))).stem or "table"
        session = SessionInfo(
            session_id=f"replay-{stem}",
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
