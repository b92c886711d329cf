"""A folder of sessions as one Parquet dataset, partitioned by subject, controller and session.

Layout (hive partitioning, one directory level per key)::

    ROOT/subject_id=S001/controller=adaptive/session_id=20261122-050650/part-0.parquet

Each row is one run's metrics for one collision event on one axis (the columns of
:func:`~hilrig.analysis.compare.metrics_frame`) with the session's metadata: rig, UTC start,
software version, controller parameters (JSON) and ``source_start_ns``, the log time of the
source's t_s = 0 (ns since the Unix epoch), so ``source_start_ns + start_s * 1e9`` places an
event in time. Subjects appear only as their pseudonymous ids. A replay result's rows go under
the session its input was recorded in (null, hive's ``__HIVE_DEFAULT_PARTITION__``, when its
metadata does not say) with each run's name as the controller. Writing a session again replaces
its partitions.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.dataset as ds

from hilrig.analysis.compare import Analysis, metrics_frame
from hilrig.errors import AnalysisError
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


def write_dataset(frame: pd.DataFrame, root: Path) -> Path:
    """Write :func:`dataset_frame` rows under ``root``, partitioned by PARTITIONS.

    Partitions already there are replaced, others kept. Raises AnalysisError if ``root`` is a
    file or cannot be written.
    """
    if root.exists() and not root.is_dir():
        raise AnalysisError(f"{root}: the dataset goes in a folder, and this is a file")
    table = pa.Table.from_pandas(frame, preserve_index=False)
    try:
        ds.write_dataset(
            table,
            root,
            format="parquet",
            partitioning=ds.partitioning(_PARTITION_SCHEMA, flavor="hive"),
            existing_data_behavior="delete_matching",
            basename_template="part-{i}.parquet",
        )
    except (OSError, pa.ArrowException) as err:
        raise AnalysisError(f"{root}: cannot write the dataset ({err})") from err
    return root


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
