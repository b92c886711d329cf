"""``hilrig sweep``: sessions through a grid of controller parameters, on this machine or a Ray
cluster, into a Parquet dataset of per-event metrics (docs/sweeps.md)."""

from __future__ import annotations

from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.errors import one_line_errors
from hilrig.cli.options import ControllerOption, SetOption, SweepOption

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rich.console import Console
    from rich.progress import Task as BarTask

    from hilrig.sweep import SweepSummary
    from hilrig.sweep.driver import Progress

#: Least seconds between two redraws of the bar.
REDRAW_S = 0.1


class EngineOption(StrEnum):
    """Where the tasks run (hilrig.sweep.engines.ENGINES)."""

    LOCAL = "local"
    RAY = "ray"


@app.command("sweep")
@one_line_errors
def sweep_command(
    sources: Annotated[
        list[Path],
        typer.Argument(
            help="Sessions (.mcap), force tables (.csv/.parquet), folders of sessions, or study "
            "folders (their sessions less the ones study.toml excludes).",
            show_default=False,
        ),
    ],
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            "-o",
            help="The results' folder: metrics/ (and tables/) Parquet datasets partitioned by "
            "source and run. Rerun into it to complete an interrupted sweep.",
            show_default=False,
        ),
    ],
    controller: ControllerOption = None,
    setting: SetOption = None,
    sweep: SweepOption = None,
    closed_loop: Annotated[
        bool,
        typer.Option(
            "--closed-loop",
            help="Predict the force each parameter set would have met (recorded sessions only; "
            "see hilrig replay --closed-loop). Default: the recorded force replayed as it is.",
        ),
    ] = False,
    tables: Annotated[
        bool,
        typer.Option("--tables", help="Write every run's full result table too (tables/)."),
    ] = False,
    engine: Annotated[
        EngineOption,
        typer.Option(help="local: a process pool on this machine; ray: Ray tasks (hilrig\\[ray])."),
    ] = EngineOption.LOCAL,
    address: Annotated[
        str | None,
        typer.Option(
            help="With --engine ray: the cluster's head, HOST:PORT (default: RAY_ADDRESS, else a "
            "Ray instance started on this machine)."
        ),
    ] = None,
    report: Annotated[
        Path | None,
        typer.Option(
            "--report",
            help="Also write the sweep's report (.html, offline): each metric against the swept "
            "parameter, with the subjects' spread, and the summary tables.",
            show_default=False,
        ),
    ] = None,
    overwrite_report: Annotated[
        bool, typer.Option("--overwrite-report", help="Replace an existing --report file.")
    ] = False,
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            "-j",
            min=1,
            help="Processes (local), or CPUs of a Ray instance started here (default: the cores).",
        ),
    ] = None,
) -> None:
    """Replay every source through every parameter set, one task each, and write each task's
    per-event metrics; a rerun skips the tasks already written.

    Ends with each parameter set's collisions across subjects: per axis group, the median over
    subjects of each subject's mean, each event on its loaded axis (docs/sweeps.md)."""
    from rich.console import Console

    from hilrig.errors import DiskError, SweepError
    from hilrig.ray_address import check_reachable, cluster_address, require_ray

    if engine is EngineOption.RAY:  # first: in seconds, before the heavy imports below
        require_ray()
        check_reachable(cluster_address(address))
    elif address is not None:
        raise SweepError("--address: only with --engine ray")

    from hilrig.cli.sweep_table import summary_tables
    from hilrig.replay.specs import parse_specs
    from hilrig.sweep import find_inputs, plan
    from hilrig.sweep import sweep as run_sweep
    from hilrig.sweep.report import check_report, write_sweep_report

    console = Console(highlight=False, soft_wrap=True)
    errors = Console(stderr=True, highlight=False, soft_wrap=True)
    specs = parse_specs(controller or [], setting or [], sweep or [])  # refused before any work
    if report is not None:
        check_report(report, overwrite=overwrite_report)
    inputs = find_inputs(sources, closed_loop=closed_loop)
    for note in inputs.notes:
        console.print(note)
    tasks = plan(inputs, specs, closed_loop=closed_loop)
    with _bar(errors) as progress:
        summary = run_sweep(
            tasks,
            out,
            tables=tables,
            engine=engine.value,
            address=address,
            workers=workers,
            progress=progress,
        )
    console.print(_summary(summary, len(inputs.files), len(specs)))
    for table in summary_tables(summary.by_run):
        console.print(table)
    if summary.by_run.empty:
        console.print("no collisions in any source: no summary" + (", no report" if report else ""))
    elif report is not None:
        try:
            written = write_sweep_report(summary, specs, report, overwrite=overwrite_report)
        except DiskError as err:
            err.add_note(f"the sweep's results are written in {summary.root}")
            raise
        console.print(f"wrote {written}", markup=False)


def _summary(summary: SweepSummary, sources: int, runs: int) -> str:
    """One line: what was swept, what was found done, where it ran and took, where it went."""
    ran = len(summary.results)
    nodes = len(summary.nodes)
    where = f"on {nodes} Ray node{'s' * (nodes != 1)}" if nodes else "on this machine"
    line = (
        f"{_count(summary.tasks, 'task')} ({_count(sources, 'source')} x "
        f"{_count(runs, 'parameter set')}): "
        f"{summary.already_done} already done, {ran} run {where} in {summary.seconds:.1f} s"
    )
    if summary.temporaries_removed:
        line += f", {summary.temporaries_removed} unfinished files of interrupted tasks removed"
    return f"{line}; metrics in {summary.root / 'metrics'}"


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'s' * (n != 1)}"


@contextmanager
def _bar(errors: Console) -> Iterator[Progress | None]:
    """A bar of tasks done, their rate and the time left, on a terminal (None otherwise),
    redrawn by the progress callback rather than a thread (the local engine forks workers)."""
    import time

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        ProgressColumn,
        TaskID,
        TextColumn,
        TimeRemainingColumn,
    )
    from rich.progress import Progress as Bar
    from rich.text import Text

    class RateColumn(ProgressColumn):
        def render(self, task: BarTask) -> Text:
            return Text("-- tasks/s" if task.speed is None else f"{task.speed:.2f} tasks/s")

    if not errors.is_terminal:
        yield None
        return
    columns = (TextColumn("sweeping"), BarColumn(), MofNCompleteColumn(), RateColumn())
    with Bar(
        *columns, TimeRemainingColumn(), console=errors, transient=True, auto_refresh=False
    ) as bar:
        task: list[TaskID] = []
        drawn = [0.0]

        def update(done: int, total: int) -> None:
            if not task:
                task.append(bar.add_task("sweep", total=total, completed=done))
            now = time.monotonic()
            redraw = done >= total or now - drawn[0] >= REDRAW_S
            bar.update(task[0], completed=done, refresh=redraw)
            if redraw:
                drawn[0] = now

        yield update
