"""Export a recording to one table per topic (Parquet or CSV, through pyarrow).

Each table has the columns of :func:`hilrig.recording.load` with the log time (int64 ns) as
its first column; ``metadata.json`` beside them holds the file's metadata records.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from hilrig.errors import RecordingError
from hilrig.recording.info import inspect
from hilrig.recording.reader import read

Format = Literal["parquet", "csv"]


def table_name(topic: str) -> str:
    """The file stem of a topic's table: ``/ft/wrist`` -> ``ft.wrist``."""
    return topic.strip("/").replace("/", ".") or "root"


def export(
    path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    fmt: Format = "parquet",
    progress: Callable[[int, int], None] | None = None,
) -> tuple[list[Path], tuple[str, ...]]:
    """Write one ``<topic>.<fmt>`` table per topic and ``metadata.json`` into ``out_dir``.

    Returns the files written and the problems met while reading (truncation, bad chunks).
    ``progress(done, total)`` is called per chunk read. Raises RecordingError for unreadable
    input or an unknown format.
    """
    if fmt not in ("parquet", "csv"):
        raise RecordingError(f"unknown export format {fmt!r} (use parquet or csv)")
    loaded = read(path, progress=progress)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for topic, frame in loaded.frames.items():
        table = pa.Table.from_pandas(frame.reset_index(), preserve_index=False)
        target = out / f"{table_name(topic)}.{fmt}"
        if fmt == "parquet":
            pq.write_table(table, target, compression="zstd")
        else:
            pa_csv.write_csv(_plain(table), target)
        written.append(target)
    metadata = out / "metadata.json"
    metadata.write_text(json.dumps(inspect(path).metadata, indent=2, sort_keys=True) + "\n")
    written.append(metadata)
    return written, loaded.problems


def _plain(table: pa.Table) -> pa.Table:
    """Dictionary (categorical) columns decoded to strings, which CSV can hold."""
    columns = [
        column.cast(column.type.value_type) if pa.types.is_dictionary(column.type) else column
        for column in table.columns
    ]
    return pa.table(columns, names=table.column_names)
