"""A sweep's output folder: one Parquet dataset per kind of result, partitioned by source and run.

Layout (hive partitioning, values encoded as pyarrow's dataset reader decodes them)::

    OUT/sweep.json                                          what was swept (checked on a rerun)
    OUT/metrics/source=S001%2Fa.mcap/run=adaptive.a1%3D10/part-0.parquet   per-event metrics
    OUT/tables/source=.../run=.../part-0.parquet            the full result table (--tables)

A task's partition files are written under hidden temporary names in their own folder and
renamed into place (:func:`hilrig.outputs.new_files`); a task is done when every partition it
owes has its final name, so a file cut short by a killed worker is never read as a result
(pyarrow's reader skips hidden files too). Temporaries left by killed workers are removed once
a sweep has completed.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
import pyarrow.parquet as pq

from hilrig.errors import DiskError, OutputError, SweepError
from hilrig.outputs import new_files
from hilrig.replay.outputs import parquet_into
from hilrig.replay.specs import ControllerSpec

METRICS, TABLES = "metrics", "tables"
PART = "part-0.parquet"
MANIFEST = "sweep.json"
FORMAT = "hilrig-sweep/1"
PARTITIONS = ("source", "run")
_SCHEMA = pa.schema([(name, pa.string()) for name in PARTITIONS])
_HIVE = ds.partitioning(_SCHEMA, flavor="hive")
#: The hidden temporaries of :func:`hilrig.outputs.temporary_beside`.
TEMPORARY_GLOB = ".*.partial*"


@dataclass(frozen=True)
class Layout:
    """Where each task's results go under ``root``."""

    root: Path

    def partition(self, kind: str, source: str, run: str) -> Path:
        """The partition file of (``source``, ``run``) in the ``kind`` dataset."""
        folder, _ = _HIVE.format((pc.field("source") == source) & (pc.field("run") == run))
        return self.root / kind / str(folder) / PART

    def owed(self, source: str, run: str, *, tables: bool) -> list[Path]:
        """The partition files a task writes."""
        kinds = (METRICS, TABLES) if tables else (METRICS,)
        return [self.partition(kind, source, run) for kind in kinds]

    def done(self, source: str, run: str, *, tables: bool) -> bool:
        """Whether every partition the task owes is in place under its final name."""
        return all(path.is_file() for path in self.owed(source, run, tables=tables))

    def write(
        self, source: str, run: str, metrics: pd.DataFrame, table: pd.DataFrame | None
    ) -> None:
        """The task's partitions, each renamed into place when all are written (one left from
        an earlier, interrupted try is replaced)."""
        paths = self.owed(source, run, tables=table is not None)
        try:
            with new_files(*paths, overwrite=True, create_folders=True) as temporaries:
                pq.write_table(arrow_table(metrics), temporaries[0])
                if table is not None:  # ``run`` as plain strings, like the partition key
                    plain = table.assign(run=table["run"].astype(str))
                    parquet_into(plain, temporaries[1], shown_as=paths[1])
        except (OSError, pa.ArrowException) as err:
            raise SweepError(f"{paths[0].parent}: cannot write the results ({err})") from err

    def remove_empty(self, *, manifest: bool, root: bool) -> bool:
        """After a failed sweep, remove its empty partition folders and, when no partition is
        left, the ``manifest`` it wrote and the ``root`` folder it made; whether any result
        is left."""
        folders = [p for kind in (METRICS, TABLES) for p in (self.root / kind).glob("**")]
        for folder in sorted(folders, key=lambda p: len(p.parts), reverse=True):
            with suppress(OSError):
                folder.rmdir()  # only when empty
        left = any((self.root / kind).exists() for kind in (METRICS, TABLES))
        if not left and manifest:
            (self.root / MANIFEST).unlink(missing_ok=True)
        if not left and root:
            with suppress(OSError):
                self.root.rmdir()
        return left

    def remove_temporaries(self) -> int:
        """Remove the temporaries killed workers left; how many there were."""
        removed = 0
        for kind in (METRICS, TABLES):
            for path in (self.root / kind).glob(f"*/*/{TEMPORARY_GLOB}"):
                with suppress(OSError):
                    path.unlink()
                    removed += 1
        return removed


def arrow_table(frame: pd.DataFrame) -> pa.Table:
    """``frame`` as an Arrow table whose text columns are ``string``, the type of the partition
    keys, so that every partition's schema merges with every other's."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    schema = pa.schema(
        [f.with_type(pa.string()) if f.type == pa.large_string() else f for f in table.schema],
        metadata=table.schema.metadata,
    )
    return table.cast(schema)


def prepare(
    root: Path,
    runs: Mapping[str, Mapping[str, Any]],
    *,
    closed_loop: bool,
    excluded: Mapping[str, list[list[Any]]] | None = None,
) -> None:
    """Check that ``root`` can take this sweep and record it in ``sweep.json``.

    ``runs`` describes each run (law, controller, settings); ``excluded`` each source's events
    a study excludes (``[group, start_ns, end_ns]``, none for a source not in it). A folder
    holding another sweep is accepted when it was the same kind (open or closed loop) and every
    run and source it shares with this one had the same description and exclusions; new ones
    are added. Raises SweepError otherwise, and for a root that is a file or a folder of
    something else.
    """
    manifest = root / MANIFEST
    if root.exists() and not root.is_dir():
        raise SweepError(f"--out {root}: a file; the sweep's results go in a folder")
    if root.is_dir() and not manifest.is_file() and any(root.iterdir()):
        raise SweepError(f"--out {root}: not empty and holds no {MANIFEST}; choose another folder")
    loop = "closed" if closed_loop else "open"
    sources = dict(excluded or {})
    known: dict[str, Any] = {}
    known_sources: dict[str, Any] = {}
    if manifest.is_file():
        stored = _read_manifest(manifest)
        if stored.get("loop") != loop:
            raise SweepError(
                f"--out {root}: holds a {stored.get('loop')}-loop sweep and this one is "
                f"{loop} loop; choose another folder"
            )
        known = dict(stored.get("runs", {}))
        name = _first_changed(known, runs)
        if name is not None:
            raise SweepError(
                f"--out {root}: run {name!r} was swept there with other settings "
                f"({json.dumps(known[name], sort_keys=True)}); name it differently or choose "
                "another folder"
            )
        known_sources = dict(stored.get("excluded_events", {}))
        source = _first_changed(known_sources, sources)
        if source is not None:
            raise SweepError(
                f"--out {root}: source {source!r} was swept there with other excluded "
                f"events ({len(known_sources[source])}, now {len(sources[source])}; the study "
                "file changed?); choose another folder"
            )
        if set(runs) <= set(known) and set(sources) <= set(known_sources):
            return
    document = {
        "format": FORMAT,
        "loop": loop,
        "runs": known | dict(runs),
        "excluded_events": known_sources | sources,
    }
    try:
        with new_files(manifest, overwrite=True, create_folders=True) as (temporary,):
            temporary.write_text(json.dumps(document, indent=1, sort_keys=True) + "\n")
    except DiskError:  # says what to do itself
        raise
    except OutputError as err:
        raise SweepError(f"--out {root}: {err}") from err


def _first_changed(known: Mapping[str, Any], new: Mapping[str, Any]) -> str | None:
    """The first key of ``new`` that ``known`` holds with another value, if any."""
    return next((key for key, value in new.items() if key in known and known[key] != value), None)


def _read_manifest(path: Path) -> dict[str, Any]:
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise SweepError(f"{path}: cannot read it ({err})") from err
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise SweepError(f"{path}: not a hilrig sweep's record ({FORMAT})")
    return document


def read_sweep(
    root: Path, kind: str = METRICS, *, columns: Sequence[str] | None = None
) -> pd.DataFrame:
    """Every row of the ``kind`` dataset under ``root`` (only ``columns`` when given), sorted
    by source, run and then the rows' own order (partition keys as strings). Raises SweepError
    if there is none."""
    folder = root / kind
    if not folder.is_dir():
        raise SweepError(f"{root}: no {kind} of a sweep in it")
    try:
        dataset = ds.dataset(folder, format="parquet", partitioning=_HIVE)
        frame: pd.DataFrame = dataset.to_table(
            columns=None if columns is None else list(columns)
        ).to_pandas()
    except (OSError, pa.ArrowException) as err:
        raise SweepError(f"{folder}: cannot read the sweep's {kind} ({err})") from err
    keys = [*PARTITIONS, *(c for c in ("event", "axis", "t_s") if c in frame.columns)]
    return frame.sort_values(keys, kind="stable", ignore_index=True)


def partition_files(root: Path, kind: str = METRICS) -> list[Path]:
    """The finished partition files of the ``kind`` dataset (temporaries not counted)."""
    return sorted((root / kind).glob(f"*/*/{PART}"))


def describe_runs(specs: Iterable[ControllerSpec]) -> dict[str, dict[str, Any]]:
    """``{run name: {law, controller, settings}}`` of ControllerSpecs, for :func:`prepare`."""
    return {
        spec.name: {
            "law": spec.law.value,
            "controller": spec.controller,
            "settings": [setting.label for setting in spec.settings],
        }
        for spec in specs
    }
