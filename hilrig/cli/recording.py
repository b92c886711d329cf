"""``hilrig info | recover | export``: look into, repair and convert MCAP session recordings.

Exit status of each: 0 the file is whole; 1 it was read but is damaged or unfinished (what is
damaged and what it cost are printed, and recover and export still write what was readable);
2 it cannot be read at all, or an output cannot be written (one ``error:`` line).
"""

from __future__ import annotations

import enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.errors import one_line_errors

if TYPE_CHECKING:
    from rich.console import Console

    from hilrig.recording.info import FileInfo

_FILE = Annotated[Path, typer.Argument(help="An MCAP recording.", show_default=False)]
#: Exit status of a file that was read but is damaged or unfinished.
DAMAGED_EXIT = 1


class ExportFormat(enum.StrEnum):
    PARQUET = "parquet"
    CSV = "csv"


def _problems(console: Console, problems: tuple[str, ...]) -> None:
    from rich.text import Text

    for line in problems:
        console.print(Text.assemble(("warning: ", "yellow"), line), soft_wrap=True)


def _exit_if_damaged(problems: tuple[str, ...]) -> None:
    if problems:
        raise typer.Exit(DAMAGED_EXIT)


@app.command("info")
@one_line_errors
def info_command(
    file: _FILE,
    check: Annotated[
        bool,
        typer.Option(
            "--check", help="Read all of it: the data section's CRC, every chunk, every record."
        ),
    ] = False,
) -> None:
    """Session metadata, topics (type, count, rate, span, gaps), the loop's counters and
    whether the file is whole.

    Exit status: 0 whole; 1 read, but damaged or unfinished; 2 cannot be read at all.
    """
    from rich.console import Console

    from hilrig.recording import inspect

    described = inspect(file, check=check)
    console = Console(highlight=False)
    if not console.is_terminal:  # keep full topic and type names when piped
        console = Console(highlight=False, width=200)
    _print_info(console, described)
    _problems(Console(stderr=True), described.problems)
    _exit_if_damaged(described.problems)


def _print_loop(console: Console, info: FileInfo) -> None:
    """The loop's end figures and how it ended (the ``outcome`` record), else its last counters
    in the file."""
    outcome = info.outcome
    if outcome is not None:
        early = " early" if outcome.ended_early else ""
        console.print(f"ended{early}: {outcome.ended}", markup=False)
        console.print(
            f"loop: {outcome.ticks:,} ticks, {outcome.hold_ticks:,} hold ticks,"
            f" {outcome.fallback_ticks:,} fallback ticks, {outcome.missed_deadlines:,} missed"
            f" deadlines ({outcome.missed_pct:.2f} %), {outcome.recorder_drops:,} recorder"
            " drops",
            markup=False,
        )
        console.print(
            f"loop timing: lateness p50/p99 {outcome.lateness_p50_us:.0f}/"
            f"{outcome.lateness_p99_us:.0f} us, compute per tick {outcome.compute_p50_us:.0f}/"
            f"{outcome.compute_p99_us:.0f} us, sensor-to-command"
            f" {outcome.sensor_to_command_p50_us:.0f}/{outcome.sensor_to_command_p99_us:.0f} us",
            markup=False,
        )
        return
    why = (
        f"its outcome record is damaged ({info.outcome_problem})"
        if info.outcome_problem
        else "no outcome record: the session did not end cleanly, or an older hilrig wrote it"
    )
    if info.loop is not None:
        loop = info.loop
        console.print(
            f"loop: {loop.overruns:,} overruns and {loop.recorder_drops:,} recorder drops by tick"
            f" {loop.tick:,}; hold ticks unknown: {why}",
            markup=False,
        )
    elif info.metadata.get("session") is not None:
        console.print(f"loop: figures unknown: {why}", markup=False)


def _print_info(console: Console, info: FileInfo) -> None:
    from rich.markup import escape
    from rich.table import Table

    from hilrig.recording.session import utc_iso

    if info.complete and info.verified:
        state = "[green]complete[/]"
    elif info.complete:
        state = "[green]complete[/] as far as read (no data CRC; `--check` reads every chunk)"
    elif info.truncated:
        state = "[bold red]TRUNCATED (unfinished; `hilrig recover` repairs it)[/]"
    elif info.problems:
        state = "[bold red]DAMAGED (`hilrig recover` keeps what is intact)[/]"
    else:
        state = "[yellow]no valid summary (`hilrig recover` rebuilds it)[/]"
    console.print(
        f"[bold]{escape(str(info.path))}[/]  {info.size:,} bytes, {info.chunks} chunks, {state}"
    )
    console.print(f"profile {info.profile!r}, written by {info.library!r}", markup=False)
    start, end = info.start_ns, info.end_ns
    if start is not None and end is not None:
        console.print(f"from {utc_iso(start)} to {utc_iso(end)} ({(end - start) / 1e9:.3f} s)")
    _print_loop(console, info)
    for name, values in info.metadata.items():
        table = Table(title=f"metadata: {escape(name)}", title_justify="left", show_header=False)
        for key, value in values.items():
            shown = value if len(value) < 200 else value[:197] + "..."
            table.add_row(escape(key), escape(shown))
        console.print(table)
    topics = Table(title="topics", title_justify="left")
    for column in ("topic", "type", "messages", "rate Hz", "start s", "span s", "max gap ms"):
        topics.add_column(column, justify="left" if column in ("topic", "type") else "right")
    topics.add_column("gaps", justify="right")
    for t in info.topics:
        rate = "-" if t.rate_hz is None else f"{t.rate_hz:.1f}"
        t0 = "-" if t.start_ns is None or start is None else f"{(t.start_ns - start) / 1e9:.3f}"
        span = (
            "-"
            if t.start_ns is None or t.end_ns is None
            else f"{(t.end_ns - t.start_ns) / 1e9:.3f}"
        )
        gap = "-" if t.max_interval_ns is None else f"{t.max_interval_ns / 1e6:.2f}"
        row = (escape(t.topic), escape(t.type), f"{t.count:,}", rate, t0, span, gap, str(t.gaps))
        topics.add_row(*row)
    console.print(topics)
    for a in info.attachments:
        line = f"attachment {a.name} ({a.media_type}, {a.data_size:,} bytes)"
        console.print(line, markup=False)


@app.command("recover")
@one_line_errors
def recover_command(
    file: _FILE,
    out: Annotated[
        Path,
        typer.Option("-o", "--out", help="Where to write the repaired file (must not exist)."),
    ],
) -> None:
    """Write a valid copy of a truncated, unfinished or damaged recording with every intact
    record; report what was damaged and lost.

    Exit status: 0 the source was whole; 1 it was damaged or unfinished (the repaired copy is
    written); 2 it cannot be read at all, or the output cannot be written (nothing is).
    """
    from rich.console import Console

    from hilrig.recording import recover

    result = recover(file, out)
    console = Console(highlight=False)
    console.print(f"wrote {result.output}", markup=False, soft_wrap=True)
    console.print(result.summary(), soft_wrap=True, markup=False)
    _exit_if_damaged(result.problems)


@app.command("export")
@one_line_errors
def export_command(
    file: _FILE,
    out: Annotated[
        Path, typer.Option("--out", help="Folder for one table per topic (made if missing).")
    ],
    fmt: Annotated[
        ExportFormat, typer.Option("--format", help="Table format.")
    ] = ExportFormat.PARQUET,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Replace tables already in --out.")
    ] = False,
) -> None:
    """Write one Parquet or CSV table per topic (and metadata.json) into --out; existing tables
    are refused unless --overwrite.

    Exit status: 0 the file is whole; 1 it was read but is damaged or unfinished (what was
    readable is written); 2 it cannot be read at all, or a table cannot be written (none is).
    """
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    from hilrig.recording import export as export_recording

    console = Console(highlight=False)
    columns = (
        TextColumn("reading chunks"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task("read", total=None)
        written, problems = export_recording(
            file,
            out,
            fmt=fmt.value,
            overwrite=overwrite,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    for path in written:
        console.print(f"wrote {path}", markup=False, soft_wrap=True)
    _problems(Console(stderr=True), problems)
    _exit_if_damaged(problems)
