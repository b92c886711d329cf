"""A folder of sessions as one Parquet dataset, partitioned by subject, controller and session.

Layout (hive partitioning, one directory level per key)::

    ROOT/subject_id=S001/controller=adaptive/session_id=01KCQ4X2ZJ8M3N6P9R1T5V7W0Y/part-0.parquet

Each row is one run's metrics for one collision event on one axis (the columns of
:func:`~hilrig.analysis.compare.metrics_frame`) with the session's metadata: rig, UTC start,
software version, controller parameters (JSON) and ``source_start_ns``, the log time of the
source's t_s = 0 (ns since the Unix epoch), so ``source_start_ns + start_s * 1e9`` places an
event in time. Subjects appear only as their pseudonymous ids. A replay result's rows go under
the session its input was recorded in (null, hive's ``__HIVE_DEFAULT_PARTITION__``, when its
metadata does not say) with each run's name as the controller. A partition already in the
dataset is refused, or with ``overwrite`` replaced (the others are kept); the partition files
are written through :func:`hilrig.outputs.new_files`, all of them or none.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
import pyarrow.parquet as pq

from hilrig.analysis.compare import Analysis, metrics_frame
from hilrig.errors import AnalysisError
from hilrig.outputs import new_files
from hilrig.recording.session import utc_iso, validate_subject_id

PARTITIONS = ("subject_id", "controller", "session_id")
SESSION_COLUMNS = (
    *PARTITIONS,
    "rig",
    "start_utc",
    "software_version",
    "controller_params",
    "source_start_ns",
)
_PARTITION_SCHEMA = pa.schema([(name, pa.string()) for name in PARTITIONS])


def dataset_frame(analyses: Sequence[Analysis]) -> pd.DataFrame:
    """The dataset's rows: per-event metrics with the session columns (see the module doc)."""
    frames = []
    for analysis in analyses:
        source, session = analysis.source, analysis.source.session
        described: dict[str, str | None] = dict.fromkeys(SESSION_COLUMNS[:-1])
        if session is not None:
            described |= {
                "controller": session.controller,
                "rig": session.rig,
                "start_utc": utc_iso(session.start_utc_ns),
                "software_version": session.software_version,
                "controller_params": json.dumps(dict(session.controller_params), sort_keys=True),
            }
        described |= {
            "subject_id": source.subject_id and validate_subject_id(source.subject_id),
            "session_id": source.session_id,
        }
        frame = metrics_frame([analysis]).assign(**described, source_start_ns=source.start_ns)
        if session is None:
            frame["controller"] = frame["run"]
        frames.append(frame)
    frame = pd.concat(frames, ignore_index=True)
    frame["source_start_ns"] = frame["source_start_ns"].astype("Int64")
    return frame[[*SESSION_COLUMNS, *(c for c in frame.columns if c not in SESSION_COLUMNS)]]


def check_dataset_root(root: Path) -> None:
    """Refuse, before any work, a dataset root that is a file (AnalysisError)."""
    if root.exists() and not root.is_dir():
        raise AnalysisError(f"{root}: the dataset goes in a folder, and this is a file")


def write_dataset(frame: pd.DataFrame, root: Path, *, overwrite: bool = False) -> Path:
    """Write :func:`dataset_frame` rows under ``root``, partitioned by PARTITIONS, one
    ``part-0.parquet`` per partition, all of them or none.

    A partition already there is refused unless ``overwrite`` (then it is replaced); the others
    are kept. Raises AnalysisError if ``root`` is a file, a partition exists, or the files cannot
    be written (OutputError for folders that cannot be).
    """
    check_dataset_root(root)
    table = pa.Table.from_pandas(frame, preserve_index=False)
    parts = _partitions(frame, table, root)
    existing = [path for path in parts if path.exists()]
    if existing and not overwrite:
        raise AnalysisError(
            f"{existing[0]}: already exists (this session's partition of the dataset); pass "
            "--overwrite to replace it"
        )
    try:
        with new_files(*parts, overwrite=overwrite, create_folders=True) as temporaries:
            for temporary, part in zip(temporaries, parts.values(), strict=True):
                pq.write_table(part, temporary)
    except (OSError, pa.ArrowException) as err:
        raise AnalysisError(f"{root}: cannot write the dataset ({err})") from err
    return root


def _partitions(frame: pd.DataFrame, table: pa.Table, root: Path) -> dict[Path, pa.Table]:
    """``{partition file: its rows without the partition columns}``, hive paths encoded as
    pyarrow's dataset writer and reader do."""
    hive = ds.partitioning(_PARTITION_SCHEMA, flavor="hive")
    groups: dict[tuple[str | None, ...], list[int]] = {}
    columns = (frame[name].tolist() for name in PARTITIONS)
    for row, key in enumerate(zip(*columns, strict=True)):
        groups.setdefault(tuple(None if pd.isna(v) else str(v) for v in key), []).append(row)
    parts: dict[Path, pa.Table] = {}
    for key, rows in groups.items():
        condition = pc.scalar(True)
        for name, value in zip(PARTITIONS, key, strict=True):
            condition &= pc.field(name).is_null() if value is None else pc.field(name) == value
        folder, _ = hive.format(condition)
        parts[root / folder / "part-0.parquet"] = table.take(rows).drop_columns(list(PARTITIONS))
    return parts


def read_dataset(root: Path) -> pd.DataFrame:
    """Every row of the dataset under ``root``, partition keys as strings (never guessed as
    numbers). Raises AnalysisError if there is none."""
    try:
        dataset = ds.dataset(
            root, format="parquet", partitioning=ds.partitioning(_PARTITION_SCHEMA, flavor="hive")
        )
        frame: pd.DataFrame = dataset.to_table().to_pandas()
    except (OSError, pa.ArrowException) as err:
        raise AnalysisError(f"{root}: cannot read the dataset ({err})") from err
    return frame
