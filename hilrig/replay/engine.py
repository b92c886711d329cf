"""The replay engine: every run over one force trace, straight into the result table's memory.

Each run is a :mod:`hilrig.control` controller started from rest, exactly what
:func:`hilrig.control.simulate` computes (the tests hold them equal to the last bit). Instead of
letting ``simulate`` allocate (T, A) arrays and then copying them into the table, the
controller's ``run_into`` writes each tick's offset, velocity, damping and stiffness directly
into the table's columns (strided views), in blocks of ticks so that progress can be reported;
force is then copied in column-wise and zeta computed in one compiled pass. That halves the
memory traffic, which is what a long replay spends its time on (see also :mod:`.blocks`, where
that memory comes from).

Results are checked as they are made: a run whose offsets or velocities stop being finite
numbers (a non-finite state never becomes finite again, so the state after each block of ticks
tells) or whose damping ratio is not finite (it is NaN or infinite whenever damping or
stiffness is) is refused with one line naming the run, the column and the first tick, and no
table is returned.

Runs go either one after the other in this process or, with ``jobs`` > 1, to a
``ProcessPoolExecutor`` of forked local processes that write into a shared anonymous mapping
(nothing is pickled but the parameters). Which is faster depends on the size: see
:func:`choose_jobs` and docs/replay.md.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.control import (
    OUTPUTS,
    AdmittanceController,
    Law,
    ParameterError,
    damping_ratio_rows,
    make,
)
from hilrig.errors import ReplayError
from hilrig.replay.blocks import Arena, Blocks
from hilrig.replay.inputs import PathLike, load_trace
from hilrig.replay.results import FLOAT_ROWS, Run, frame, table_bytes
from hilrig.replay.specs import ControllerSpec, parse_specs
from hilrig.replay.trace import ForceTrace

#: ``progress(phase, done, total)``: phase "load" counts an MCAP file's chunks, "replay" ticks
#: of all runs together.
Progress = Callable[[str, int, int], None]
#: Ticks per kernel call: progress granularity (about 20 ms of work on 9 axes).
BLOCK_TICKS = 1 << 18
#: The process pool pays only for runs whose ticks are all full kernel steps - the state
#: machine off and a law that is not fixed, so no quiet tick takes the kernel's shortcut - and
#: only with at least two of them holding this many axis-ticks together. Measured (docs/replay.md):
#: otherwise the runs are memory-bound, and forking plus the shared mapping's page faults cost
#: more than the second core saves.
POOL_MIN_HEAVY_AXIS_TICKS = 4_000_000


def run(
    source: PathLike | ForceTrace,
    controllers: Sequence[ControllerSpec] | None = None,
    *,
    jobs: int | None = None,
    resample: bool = False,
    progress: Progress | None = None,
) -> pd.DataFrame:
    """Replay ``source`` (a file for :func:`.load_trace`, or a trace) through ``controllers``
    (default: the three laws with the live loop's presets); returns the result table of
    :mod:`.results`. Raises ReplayError (one line) for unusable input or parameters."""
    if isinstance(source, ForceTrace):
        trace = source
    else:
        load_progress = None if progress is None else _phase(progress, "load")
        trace = load_trace(source, resample=resample, progress=load_progress)
    specs = parse_specs() if controllers is None else controllers
    return replay(trace, runs_of(trace, specs), jobs=jobs, progress=progress)


def runs_of(trace: ForceTrace, specs: Sequence[ControllerSpec]) -> list[Run]:
    """The runs of ``specs`` on ``trace``, after the size of their result table is checked
    (:func:`check_table_size`: refused before any run is built); raises ReplayError."""
    check_table_size(trace, len(specs))
    return [Run.from_spec(spec, trace.axis_names) for spec in specs]


def check_table_size(trace: ForceTrace, runs: int) -> None:
    """Refuse ``runs`` runs over ``trace`` whose result table would not fit in this machine's
    memory (ReplayError naming both sizes)."""
    ticks = trace.ticks
    need = table_bytes(len(trace.axis_names), ticks * runs)
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have:
        raise ReplayError(
            f"{runs} run{'s' * (runs != 1)} of {ticks} ticks need a {need / 2**30:.1f} GiB "
            f"table, more than this machine's {have / 2**30:.1f} GiB; replay fewer runs or a "
            "shorter input"
        )


def _phase(progress: Progress, phase: str) -> Callable[[int, int], None]:
    return lambda done, total: progress(phase, done, total)


def replay(
    trace: ForceTrace,
    runs: Sequence[Run],
    *,
    jobs: int | None = None,
    progress: Progress | None = None,
    arena: Arena | None = None,
) -> pd.DataFrame:
    """The result table of ``runs`` over ``trace``. ``jobs``: processes (1 = this one; None =
    :func:`choose_jobs`); ``arena``: where the table's memory comes from when the runs go in
    this process (:mod:`.blocks`). Raises ReplayError for invalid parameters, duplicate run
    names or a table larger than this machine's memory."""
    if not runs:
        raise ReplayError("no controller runs to replay")
    names = [r.name for r in runs]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ReplayError(f"run names repeat: {', '.join(repeated)}")
    axes, ticks = len(trace.axis_names), trace.ticks
    check_table_size(trace, len(runs))
    controllers = [_controller(r, trace) for r in runs]
    force = np.require(trace.force, np.float64, ["C_CONTIGUOUS", "WRITEABLE"])
    workers = choose_jobs(runs, axes * ticks) if jobs is None else max(1, jobs)
    workers = min(workers, len(runs))
    report = _Report(progress, ticks * len(runs))
    pool = workers > 1 and "fork" in multiprocessing.get_all_start_methods()
    blocks = Blocks.allocate(axes, len(FLOAT_ROWS), ticks * len(runs), shared=pool, arena=arena)
    found: list[NonFinite | None] = []
    if pool:
        _warm_up(force, controllers[0], blocks)  # compile before forking: once, not per process
        found = _in_pool(force, controllers, blocks, workers, report)
    else:
        for index, controller in enumerate(controllers):
            found.append(simulate_into(force, controller, blocks, index * ticks, report.add))
            if found[-1] is not None:
                break
    blocks.settle()
    for index, bad in enumerate(found):
        if bad is not None:
            raise ReplayError(bad.describe(runs[index], trace))
    return frame(trace, runs, blocks)


def choose_jobs(runs: Sequence[Run], axis_ticks: int) -> int:
    """Processes for ``runs`` of ``axis_ticks`` axis-ticks each: the local cores when the pool
    pays (see POOL_MIN_HEAVY_AXIS_TICKS), else 1."""
    heavy = sum(1 for r in runs if not r.params.state_machine and r.law is not Law.FIXED)
    cores = local_cores()
    if heavy >= 2 and heavy * axis_ticks >= POOL_MIN_HEAVY_AXIS_TICKS and cores > 1:
        return min(len(runs), cores)
    return 1


def local_cores() -> int:
    """The cores this process may run on."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return cores or 1


def _controller(run: Run, trace: ForceTrace) -> AdmittanceController:
    try:
        return make(run.law, run.params, len(trace.axis_names), trace.dt_s)
    except ParameterError as err:
        raise ReplayError(f"run {run.name}: {err}") from err


@dataclass(frozen=True)
class NonFinite:
    """The first value of a run's result that is not a finite number."""

    quantity: str  # a FLOAT_ROWS name
    axis: int
    tick: int
    value: float

    def describe(self, run: Run, trace: ForceTrace) -> str:
        column = f"{self.quantity}_{trace.axis_names[self.axis]}"
        return (
            f"run {run.name} ({run.law.value}): column {column} is {self.value} at tick "
            f"{self.tick} (t = {trace.t_s[self.tick]:.6g} s), its first value that is not "
            "finite; the result is refused"
        )


def _first_nonfinite(
    columns: dict[str, NDArray[np.float64]], quantities: Sequence[str], tick0: int
) -> NonFinite | None:
    """The earliest non-finite value of ``columns[q]`` (A, T) over ``quantities``, if any."""
    found: NonFinite | None = None
    for quantity in quantities:
        bad = ~np.isfinite(columns[quantity])
        if bad.any():
            tick = int(np.argmax(bad.any(axis=0)))
            axis = int(np.argmax(bad[:, tick]))
            if found is None or tick0 + tick < found.tick:
                value = float(columns[quantity][axis, tick])
                found = NonFinite(quantity, axis, tick0 + tick, value)
    return found


@dataclass
class _Report:
    """Counts ticks done over all runs and passes them on to the progress callback."""

    progress: Progress | None
    total: int
    done: int = 0

    def add(self, ticks: int) -> None:
        self.done += ticks
        if self.progress is not None:
            self.progress("replay", self.done, self.total)


def simulate_into(
    force: NDArray[np.float64],
    controller: AdmittanceController,
    blocks: Blocks,
    row0: int,
    on_block: Callable[[int], None] | None = None,
) -> NonFinite | None:
    """Run ``controller`` from rest over ``force`` (T, A), writing rows ``row0`` ..
    ``row0 + T`` of ``blocks``; ``on_block(ticks)`` after each block of ticks. Stops at the
    first block whose result is not finite and returns where (None when all is finite)."""
    ticks = force.shape[0]
    controller.reset()
    floats, contact = blocks.floats, blocks.contact
    for start in range(0, ticks, BLOCK_TICKS):
        stop = min(start + BLOCK_TICKS, ticks)
        rows = slice(row0 + start, row0 + stop)
        out = floats[:, : len(OUTPUTS), rows].transpose(1, 2, 0)  # (outputs, ticks, axes) view
        controller.run_into(force[start:stop], out, contact[:, rows].T)
        if on_block is not None:
            on_block(stop - start)
        # a non-finite offset or velocity stays non-finite: the last tick's state tells
        if not (np.isfinite(controller.offset).all() and np.isfinite(controller.velocity).all()):
            block = {q: floats[:, FLOAT_ROWS[q], rows] for q in ("offset", "velocity")}
            return _first_nonfinite(block, ("offset", "velocity"), start)
    rows = slice(row0, row0 + ticks)
    column = {quantity: floats[:, row, rows] for quantity, row in FLOAT_ROWS.items()}
    column["force"][:] = force.T
    damping_ratio_rows(column["damping"], column["stiffness"], controller.mass, column["zeta"])
    # zeta >= 0, and NaN or +inf wherever damping or stiffness is not finite: its max tells
    if ticks and not np.isfinite(np.max(column["zeta"])):
        return _first_nonfinite(column, ("zeta",), 0)
    return None


# -- the process pool -------------------------------------------------------------------------


@dataclass(frozen=True)
class _Shared:
    """What forked workers inherit: the input, the runs' controllers and the shared result
    blocks (so nothing but indices is pickled)."""

    force: NDArray[np.float64]
    controllers: Sequence[AdmittanceController]
    blocks: Blocks


_inherited: list[_Shared] = []


def _init_worker(shared: _Shared) -> None:
    _inherited.append(shared)


def _work(index: int, row0: int) -> NonFinite | None:
    shared = _inherited[-1]
    return simulate_into(shared.force, shared.controllers[index], shared.blocks, row0)


def _warm_up(force: NDArray[np.float64], controller: AdmittanceController, blocks: Blocks) -> None:
    """One tick through the kernel with the block's array layouts, so forked workers inherit
    the compiled code (the row is overwritten by the real run later)."""
    simulate_into(force[:1], controller, blocks, 0)


def _in_pool(
    force: NDArray[np.float64],
    controllers: Sequence[AdmittanceController],
    blocks: Blocks,
    workers: int,
    report: _Report,
) -> list[NonFinite | None]:
    """Every run in the pool; what each found (see :func:`simulate_into`), in run order."""
    ticks = force.shape[0]
    context = multiprocessing.get_context("fork")
    sys.stdout.flush()
    sys.stderr.flush()
    with ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=_init_worker,
        initargs=(_Shared(force, controllers, blocks),),
    ) as pool:
        futures = [pool.submit(_work, i, i * ticks) for i in range(len(controllers))]
        for future in as_completed(futures):
            future.result()
            report.add(ticks)
    return [future.result() for future in futures]
