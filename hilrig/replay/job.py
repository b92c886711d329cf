"""One offline replay job, as ``hilrig replay`` runs it: outputs checked before any work, the
trace loaded, its runs replayed into one table, the table written to each output.

    outputs = check_outputs([Path("results.parquet")])
    replayed = replay_file("session.mcap", parse_specs(["adaptive", "fixed"]))
    write_outputs(replayed, outputs)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hilrig.errors import ReplayError
from hilrig.replay.engine import Progress, replay
from hilrig.replay.inputs import PathLike, load_trace
from hilrig.replay.outputs import MCAP_SUFFIXES, PARQUET_SUFFIXES, write_mcap, write_parquet
from hilrig.replay.results import Run, peak_offsets
from hilrig.replay.specs import ControllerSpec
from hilrig.replay.trace import ForceTrace


@dataclass(frozen=True)
class Replayed:
    """A trace and its runs' result table (one row per run and tick)."""

    trace: ForceTrace
    runs: list[Run]
    table: pd.DataFrame

    def peak_offsets(self) -> dict[str, dict[str, float]]:
        """Per run and axis, the largest |offset|: m for x, y, z and rad for joints."""
        return peak_offsets(self.table, self.trace.axis_names)


def check_outputs(paths: Sequence[Path]) -> list[Path]:
    """``paths`` if each can be written: a known suffix (Parquet or MCAP), no file there yet, an
    existing directory, none given twice; else ReplayError naming it."""
    known = PARQUET_SUFFIXES + MCAP_SUFFIXES
    for path in paths:
        if path.suffix.lower() not in known:
            raise ReplayError(f"--out {path}: unknown output type; known: {', '.join(known)}")
        if path.exists():
            raise ReplayError(f"--out {path}: already exists; refusing to overwrite it")
        if not path.parent.is_dir():
            raise ReplayError(f"--out {path}: directory {path.parent} does not exist")
    if len(set(paths)) != len(paths):
        raise ReplayError("--out: the same file is given twice")
    return list(paths)


def replay_file(
    path: PathLike,
    specs: Sequence[ControllerSpec],
    *,
    resample: bool = False,
    jobs: int | None = None,
    progress: Progress | None = None,
) -> Replayed:
    """The trace in ``path`` replayed through ``specs``; ``progress(phase, done, total)``
    follows the phases ``load`` and ``replay``."""
    trace = load_trace(
        path,
        resample=resample,
        progress=None if progress is None else lambda done, total: progress("load", done, total),
    )
    runs = [Run.from_spec(spec, trace.axis_names) for spec in specs]
    return Replayed(trace, runs, replay(trace, runs, jobs=jobs, progress=progress))


def write_outputs(
    replayed: Replayed, paths: Sequence[Path], *, progress: Progress | None = None
) -> None:
    """The result table to each of ``paths``: Parquet (the table) or MCAP (one topic per run,
    the ``write`` phase of ``progress``)."""
    for path in paths:
        if path.suffix.lower() in PARQUET_SUFFIXES:
            write_parquet(replayed.table, path)
        else:
            write_mcap(
                replayed.table,
                path,
                session=replayed.trace.session,
                t0_ns=replayed.trace.t0_ns,
                progress=None if progress is None else lambda d, t: progress("write", d, t),
            )
