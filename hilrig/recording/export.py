"""Export a recording to one table per topic (Parquet or CSV, through pyarrow).

Each table has the columns of :func:`hilrig.recording.load` with the log time (int64 ns) as
its first column; ``metadata.json`` beside them holds the file's readable metadata records.
The tables are written through :func:`hilrig.outputs.new_files`: every target checked before
the file is read, all of them moved into place at the end, or none.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from hilrig.errors import OutputError, RecordingError
from hilrig.outputs import check_new_file, new_files
from hilrig.recording.reader import read

Format = Literal["parquet", "csv"]
METADATA_FILE = "metadata.json"
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")


def table_name(topic: str) -> str:
    """The file stem of a topic's table: ``/ft/wrist`` -> ``ft.wrist`` (characters other than
    letters, digits, ``_``, ``.`` and ``-`` become ``_``)."""
    return _UNSAFE.sub("_", topic.strip("/").replace("/", ".")) or "root"


def export(
    path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    fmt: Format = "parquet",
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[list[Path], tuple[str, ...]]:
    """Write one ``<topic>.<fmt>`` table per topic and ``metadata.json`` into ``out_dir``
    (created if missing).

    Returns the files written and the problems met while reading (truncation, damage).
    ``progress(done, total)`` is called per chunk read. Raises RecordingError for unreadable
    input or an unknown format, OutputError when a table exists (unless ``overwrite``) or
    cannot be written; then nothing is left behind (a folder it made is removed again).
    """
    if fmt not in ("parquet", "csv"):
        raise RecordingError(f"unknown export format {fmt!r} (use parquet or csv)")
    out = Path(out_dir)
    check_new_file(out / METADATA_FILE, overwrite=overwrite, create_folder=True)
    loaded = read(path, progress=progress)
    targets = [out / f"{table_name(topic)}.{fmt}" for topic in loaded.frames]
    finals = [*targets, out / METADATA_FILE]
    with new_files(*finals, overwrite=overwrite, create_folders=True) as temporaries:
        for frame, temporary, final in zip(
            loaded.frames.values(), temporaries, finals, strict=False
        ):
            table = pa.Table.from_pandas(frame.reset_index(), preserve_index=False)
            try:
                if fmt == "parquet":
                    pq.write_table(table, temporary, compression="zstd")
                else:
                    pa_csv.write_csv(_plain(table), temporary)
            except (OSError, pa.ArrowException) as err:
                raise OutputError(f"{final}: cannot be written ({err})") from err
        metadata = json.dumps(loaded.index.values, indent=2, sort_keys=True) + "\n"
        try:
            temporaries[-1].write_text(metadata)
        except OSError as err:
            raise OutputError(f"{finals[-1]}: cannot be written ({err.strerror})") from err
    return finals, loaded.problems


def _plain(table: pa.Table) -> pa.Table:
    """Dictionary (categorical) columns decoded to strings, which CSV can hold."""
    columns = [
        column.cast(column.type.value_type) if pa.types.is_dictionary(column.type) else column
        for column in table.columns
    ]
    return pa.table(columns, names=table.column_names)
