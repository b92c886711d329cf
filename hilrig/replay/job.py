"""One offline replay job, as ``hilrig replay`` runs it: every output checked before any work,
the trace loaded, the size of its result checked, its runs replayed into one table (refused if
anything in it is not finite), and the table written to every output or to none.

    with replay_outputs([Path("results.parquet"), Path("results.mcap")]) as outputs:
        replayed = replay_file("session.mcap", parse_specs(["adaptive", "fixed"]))
        write_outputs(replayed, outputs)
    # both files are in place now, or neither is

The outputs go through :func:`hilrig.outputs.new_files`: each path is checked when the block
starts (a known suffix, no file there, a writable folder, none named twice), written under a
hidden temporary name beside it, and moved into place when the block ends without an error.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hilrig.errors import ReplayError
from hilrig.outputs import new_files
from hilrig.replay.blocks import Arena
from hilrig.replay.counterfactual import closed_loop
from hilrig.replay.engine import Progress, replay, runs_of
from hilrig.replay.inputs import MCAP_SUFFIXES as INPUT_MCAP_SUFFIXES
from hilrig.replay.inputs import PathLike, load_trace
from hilrig.replay.outputs import MCAP_SUFFIXES, PARQUET_SUFFIXES, mcap_into, parquet_into
from hilrig.replay.results import Run, peak_offsets
from hilrig.replay.session_world import load_world
from hilrig.replay.specs import ControllerSpec
from hilrig.replay.trace import ForceTrace
from hilrig.replay.verify import recorded_controller
from hilrig.robot import RobotModel
from hilrig.world.contact import Mechanics

#: What ``--out`` may name, by suffix.
OUTPUT_SUFFIXES = PARQUET_SUFFIXES + MCAP_SUFFIXES


@dataclass(frozen=True)
class Replayed:
    """A trace and its runs' result table (one row per run and tick)."""

    trace: ForceTrace
    runs: list[Run]
    table: pd.DataFrame

    def peak_offsets(self) -> dict[str, dict[str, float]]:
        """Per run and axis, the largest |offset|: m for x, y, z and rad for joints."""
        return peak_offsets(self.table, self.trace.axis_names)


@dataclass(frozen=True)
class Output:
    """An output file: where it goes (``path``) and where it is written first."""

    path: Path
    temporary: Path


@contextmanager
def replay_outputs(paths: Sequence[Path]) -> Iterator[list[Output]]:
    """Check ``paths`` before any work and yield where to write each; when the block ends they
    are all moved into place, after an error none is (and nothing is left behind).

    Raises ReplayError for an unknown suffix, OutputError (from :mod:`hilrig.outputs`) for a
    path that exists, a missing or read-only folder, or a path named twice.
    """
    for path in paths:
        if path.suffix.lower() not in OUTPUT_SUFFIXES:
            known = ", ".join(OUTPUT_SUFFIXES)
            raise ReplayError(f"--out {path}: unknown output type; known: {known}")
    with new_files(*paths) as temporaries:
        yield [Output(p, t) for p, t in zip(paths, temporaries, strict=True)]


def replay_file(
    path: PathLike,
    specs: Sequence[ControllerSpec],
    *,
    resample: bool = False,
    jobs: int | None = None,
    progress: Progress | None = None,
    arena: Arena | None = None,
) -> Replayed:
    """The trace in ``path`` replayed through ``specs``; ``progress(phase, done, total)``
    follows the phases ``load`` and ``replay``; ``arena`` as :func:`.engine.replay`. Raises
    ReplayError (one line) for an input, parameters or a result size that cannot be replayed,
    and for a result that is not finite."""
    if resample and Path(path).suffix.lower() in INPUT_MCAP_SUFFIXES:
        raise ReplayError(
            f"{path}: --resample is for CSV and Parquet tables; a recording is replayed at "
            "its loop's period as it is"
        )
    trace = load_trace(
        path,
        resample=resample,
        progress=None if progress is None else lambda done, total: progress("load", done, total),
    )
    return replay_trace(trace, specs, jobs=jobs, progress=progress, arena=arena)


def replay_trace(
    trace: ForceTrace,
    specs: Sequence[ControllerSpec],
    *,
    jobs: int | None = None,
    progress: Progress | None = None,
    arena: Arena | None = None,
) -> Replayed:
    """A loaded ``trace`` replayed through ``specs``, as :func:`replay_file` does after loading
    (the trace is only read: one trace may be replayed again and again)."""
    runs = runs_of(trace, specs)
    table = replay(trace, runs, jobs=jobs, progress=progress, arena=arena)
    return Replayed(trace, runs, table)


def check_closed_input(path: PathLike) -> Path:
    """``path`` if it can be replayed closed loop (a recording); else ReplayError (one line)."""
    p = Path(path)
    if p.suffix.lower() not in INPUT_MCAP_SUFFIXES:
        raise ReplayError(
            f"{p}: --closed-loop needs a recorded session (.mcap): the contact is fitted from "
            "the recorded force and the robot's measured motion"
        )
    return p


def closed_replay_file(
    path: PathLike,
    specs: Sequence[ControllerSpec],
    *,
    mechanics: Mechanics | None = None,
    progress: Progress | None = None,
) -> Replayed:
    """The recording ``path`` replayed through ``specs`` closed loop
    (:mod:`hilrig.replay.counterfactual`): its world fitted (``mechanics`` forces one contact
    model; None: the better fit), the recorded controller re-simulated, then each run. The
    table's ``hilrig.input`` holds ``closed_loop`` (models, fits, reproduction error).
    ``progress`` follows the phases ``fit`` and ``closed`` (in runs). Raises ReplayError (one
    line) for an input that is not a recording of the live loop or a collision too poorly fitted
    to predict from."""
    p = check_closed_input(path)
    if progress is not None:
        progress("fit", 0, 1)
    model = RobotModel()
    world = load_world(p, model, mechanics=mechanics)
    if progress is not None:
        progress("fit", 1, 1)
    law, params, _ = recorded_controller(p, world.index, world.trace.axis_names)
    runs = [Run.from_spec(spec, world.trace.axis_names) for spec in specs]
    table, _ = closed_loop(
        world,
        runs,
        Run("recorded", law, params),
        progress=None if progress is None else lambda d, t: progress("closed", d, t),
    )
    return Replayed(world.trace, runs, table)


def write_outputs(
    replayed: Replayed, outputs: Sequence[Output], *, progress: Progress | None = None
) -> None:
    """The result table to each output's temporary: Parquet (the table) or MCAP (one topic per
    run, the ``write`` phase of ``progress``)."""
    for output in outputs:
        if output.path.suffix.lower() in PARQUET_SUFFIXES:
            parquet_into(replayed.table, output.temporary, shown_as=output.path)
        else:
            mcap_into(
                replayed.table,
                output.temporary,
                session=replayed.trace.session,
                t0_ns=replayed.trace.t0_ns,
                progress=None if progress is None else lambda d, t: progress("write", d, t),
                shown_as=output.path,
            )
