"""``hilrig replay``: recorded force traces through any controllers offline, or ``--verify``."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from hilrig.cli.app import app
from hilrig.cli.record import endpoints_from_config, print_result, read_config
from hilrig.cli.recording import _one_line_errors
from hilrig.errors import ReplayError
from hilrig.replay import ForceTrace, Run, load_trace, parse_specs, peak_offsets, replay
from hilrig.replay.outputs import MCAP_SUFFIXES, PARQUET_SUFFIXES, write_mcap, write_parquet
from hilrig.replay.verify import summary_lines, verify
from hilrig.rig import LoopConfig, RigKind, SessionConfig, VirtualInput, record_session

#: Inputs at least this large get a progress bar.
LONG_INPUT_BYTES = 16 << 20
PHASES = {"load": "reading chunks", "replay": "replaying ticks", "write": "writing ticks"}
REDRAW_S = 0.1
#: Exit status of a failed --verify (2 is an error that stopped the command).
VERIFY_FAILED = 1


@app.command("replay")
@_one_line_errors
def replay_command(
    file: Annotated[
        Path,
        typer.Argument(
            help="An MCAP session, or a CSV/Parquet table (t, fx fy fz, tau1..tau6).",
            show_default=False,
        ),
    ],
    controller: Annotated[
        list[str] | None,
        typer.Option(
            "--controller",
            "-c",
            help="A controller: LAW or NAME=LAW (adaptive, variable-stiffness, fixed). "
            "Repeat for several; default: all three laws.",
        ),
    ] = None,
    setting: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            help="NAME.[cartesian.|joint.]PARAM=VALUE, e.g. adaptive.a1=10 (repeatable).",
        ),
    ] = None,
    sweep: Annotated[
        list[str] | None,
        typer.Option(
            help="NAME.[GROUP.]PARAM=START:STOP:COUNT or =V1,V2,..; sweeps of one controller "
            "run as a grid (repeatable).",
        ),
    ] = None,
    out: Annotated[
        list[Path] | None,
        typer.Option(
            "--out", "-o", help="Write the results: .parquet (the table) or .mcap (topics)."
        ),
    ] = None,
    check: Annotated[
        bool,
        typer.Option(
            "--verify",
            help="Replay the session through its recorded controller and compare with the "
            "recorded state (exit 1 if anything differs by more than 1e-12).",
        ),
    ] = False,
    resample: Annotated[
        bool,
        typer.Option(help="Interpolate a table with non-uniform times onto a uniform grid."),
    ] = False,
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", "-j", min=1, help="Processes (default: chosen by size)."),
    ] = None,
    rig: Annotated[
        RigKind | None,
        typer.Option(
            help="HIL replay: play the trace into a live rig (emulated, or aubo with --config) "
            "as a virtual collision and record the new session to --out."
        ),
    ] = None,
    subject: Annotated[
        str | None, typer.Option(help="HIL replay: pseudonymous subject id (default: FILE's).")
    ] = None,
    rate: Annotated[float, typer.Option(help="HIL replay: loop rate, Hz.")] = 1000.0,
    start: Annotated[float, typer.Option(help="HIL replay: from this time of FILE, s.")] = 0.0,
    duration: Annotated[
        float | None, typer.Option(help="HIL replay: this much of FILE, s (default: the rest).")
    ] = None,
    config: Annotated[
        Path | None, typer.Option(help="HIL replay on --rig aubo: TOML with [endpoints].")
    ] = None,
) -> None:
    """Replay FILE's force trace through controllers and sweeps; summarise the peak offsets."""
    console = Console(highlight=False)
    if not console.is_terminal:  # keep whole run names when piped
        console = Console(highlight=False, width=200)
    errors = Console(stderr=True, highlight=False, soft_wrap=True)
    long_input = file.is_file() and file.stat().st_size >= LONG_INPUT_BYTES
    if check:
        if controller or setting or sweep or out or resample:
            raise ReplayError(
                "--verify replays the recorded controller: it takes no --controller, --set, "
                "--sweep, --out or --resample"
            )
        with _progress(errors, enabled=long_input) as progress:
            report = verify(file, progress=progress)
        for line in summary_lines(report):
            console.print(line, soft_wrap=True)
        if not report.ok:
            raise typer.Exit(VERIFY_FAILED)
        return
    if rig is not None:
        if controller or setting or sweep or check or resample or jobs:
            raise ReplayError(
                "--rig replays into the live loop's controller: it takes no --controller, --set, "
                "--sweep, --verify, --resample or --jobs"
            )
        _replay_into_rig(file, rig, subject, rate, start, duration, config, out or [])
        return
    specs = parse_specs(controller or [], setting or [], sweep or [])
    outputs = _outputs(out or [])
    with _progress(errors, enabled=long_input) as progress:
        trace = load_trace(
            file,
            resample=resample,
            progress=None if progress is None else lambda d, t: progress("load", d, t),
        )
        runs = [Run.from_spec(spec, trace.axis_names) for spec in specs]
        table = replay(trace, runs, jobs=jobs, progress=progress)
        for note in trace.notes:
            errors.print(Text.assemble(("note: ", "yellow"), note))
        for path in outputs:
            if path.suffix.lower() in PARQUET_SUFFIXES:
                write_parquet(table, path)
            else:
                write_mcap(
                    table,
                    path,
                    session=trace.session,
                    t0_ns=trace.t0_ns,
                    progress=None if progress is None else lambda d, t: progress("write", d, t),
                )
    for path in outputs:
        console.print(f"wrote {path}")
    console.print(_summary(trace, table_runs=runs, peaks=peak_offsets(table, trace.axis_names)))


def _outputs(paths: list[Path]) -> list[Path]:
    """Checked before any work: a known suffix, no existing file, an existing directory."""
    for path in paths:
        if path.suffix.lower() not in PARQUET_SUFFIXES + MCAP_SUFFIXES:
            known = ", ".join(PARQUET_SUFFIXES + MCAP_SUFFIXES)
            raise ReplayError(f"--out {path}: unknown output type; known: {known}")
        if path.exists():
            raise ReplayError(f"--out {path}: already exists; refusing to overwrite it")
        if not path.parent.is_dir():
            raise ReplayError(f"--out {path}: directory {path.parent} does not exist")
    if len(set(paths)) != len(paths):
        raise ReplayError("--out: the same file is given twice")
    return paths


@contextmanager
def _progress(console: Console, *, enabled: bool) -> Iterator[_Phases | None]:
    """A transient progress bar on stderr, one task per phase (load, replay, write), redrawn
    by the callbacks rather than by rich's refresh thread: the engine may fork a process pool,
    and a fork must not happen while another thread holds the terminal's lock."""
    if not enabled:
        yield None
        return
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
    with Progress(
        *columns, TimeRemainingColumn(), console=console, transient=True, auto_refresh=False
    ) as bar:
        yield _Phases(bar)


class _Phases:
    """``progress(phase, done, total)`` onto one rich task per phase."""

    def __init__(self, bar: Progress) -> None:
        self.bar = bar
        self.tasks: dict[str, TaskID] = {}
        self.drawn = 0.0

    def __call__(self, phase: str, done: int, total: int) -> None:
        task = self.tasks.get(phase)
        if task is None:
            task = self.tasks[phase] = self.bar.add_task(PHASES.get(phase, phase), total=total)
        now = time.monotonic()
        redraw = done >= total or now - self.drawn >= REDRAW_S
        self.bar.update(task, completed=done, total=total, refresh=redraw)
        if redraw:
            self.drawn = now


def _summary(
    trace: ForceTrace, *, table_runs: list[Run], peaks: dict[str, dict[str, float]]
) -> Table:
    """Per run, the largest |offset| per axis: mm for x, y, z and mrad for joints."""
    table = Table(
        title=f"max |offset| (x y z: mm, joints: mrad) over {trace.duration_s:.3f} s of "
        f"{trace.source}",
        title_justify="left",
    )
    table.add_column("run", overflow="fold")
    for axis in trace.axis_names:
        table.add_column(axis.replace("joint", "j"), justify="right")
    for run in table_runs:
        table.add_row(run.name, *(f"{1000 * peaks[run.name][a]:.2f}" for a in trace.axis_names))
    return table


def _replay_into_rig(
    file: Path,
    rig: RigKind,
    subject: str | None,
    rate_hz: float,
    start_s: float,
    duration_s: float | None,
    config: Path | None,
    out: list[Path],
) -> None:
    """HIL replay: FILE's trace as a virtual collision in a live session, recorded to --out."""
    trace = load_trace(file)
    virtual = VirtualInput.from_columns(
        trace.t_s, trace.columns, start_s=start_s, duration_s=duration_s
    )
    subject_id = subject or (trace.session.subject_id if trace.session is not None else None)
    if subject_id is None:
        raise ReplayError(f"{file}: no subject id in the file: pass --subject")
    if len(out) > 1 or (out and out[0].suffix.lower() not in MCAP_SUFFIXES):
        raise ReplayError("--rig records one new session: pass at most one --out FILE.mcap")
    path = (
        out[0]
        if out
        else Path("recordings") / f"{subject_id}-replay-{time.strftime('%Y%m%d-%H%M%S')}.mcap"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    settings = read_config(config) if config is not None else {}
    session = SessionConfig(
        out=path,
        subject_id=subject_id,
        scenario="none",
        rig=rig,
        endpoints=endpoints_from_config(config, settings) if config is not None else None,
        duration_s=virtual.delay_s + virtual.duration_s + 2.0,  # and 2 s to recover
        trajectory="hold",
        loop=LoopConfig(rate_hz=rate_hz),
        virtual=virtual,
        virtual_source=f"{file} from {start_s} s for {virtual.duration_s:.3f} s",
    )
    result = record_session(session, stop=threading.Event())
    print_result(Console(soft_wrap=True, highlight=False), result)
    if result.recorder_error:
        raise ReplayError(f"the recording is incomplete: {result.recorder_error}")
