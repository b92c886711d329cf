"""``hilrig info | recover | export``: look into, repair and convert MCAP session recordings."""

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


class ExportFormat(enum.StrEnum):
    PARQUET = "parquet"
    CSV = "csv"


def _problems(console: Console, problems: tuple[str, ...]) -> None:
    from rich.text import Text

    for line in problems:
        console.print(Text.assemble(("warning: ", "yellow"), line), soft_wrap=True)


@app.command("info")
@one_line_errors
def info_command(
    file: _FILE,
    check: Annotated[
        bool, typer.Option("--check", help="Decompress every chunk and verify its CRC.")
    ] = False,
) -> None:
    """Session metadata, topics (type, count, rate, span, gaps) and whether the file is whole."""
    from rich.console import Console

    from hilrig.recording import inspect

    described = inspect(file, check=check)
    console = Console(highlight=False)
    if not console.is_terminal:  # keep full topic and type names when piped
        console = Console(highlight=False, width=200)
    _print_info(console, described)
    _problems(Console(stderr=True), described.problems)


def _print_info(console: Console, info: FileInfo) -> None:
    from rich.table import Table

    from hilrig.recording.session import utc_iso

    if info.complete:
        state = "[green]complete[/]"
    elif info.truncated:
        state = "[bold red]TRUNCATED (unfinished; `hilrig recover` repairs it)[/]"
    else:
        state = "[yellow]no valid summary (`hilrig recover` rebuilds it)[/]"
    console.print(f"[bold]{info.path}[/]  {info.size:,} bytes, {info.chunks} chunks, {state}")
    console.print(f"profile {info.profile!r}, written by {info.library!r}")
    start, end = info.start_ns, info.end_ns
    if start is not None and end is not None:
        console.print(f"from {utc_iso(start)} to {utc_iso(end)} ({(end - start) / 1e9:.3f} s)")
    for name, values in info.metadata.items():
        table = Table(title=f"metadata: {name}", title_justify="left", show_header=False)
        for key, value in values.items():
            table.add_row(key, value if len(value) < 200 else value[:197] + "...")
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
        topics.add_row(t.topic, t.type, f"{t.count:,}", rate, t0, span, gap, str(t.gaps))
    console.print(topics)
    for a in info.attachments:
        console.print(f"attachment {a.name} ({a.media_type}, {a.data_size:,} bytes)")


@app.command("recover")
@one_line_errors
def recover_command(
    file: _FILE,
    out: Annotated[Path, typer.Option("-o", "--out", help="Where to write the repaired file.")],
) -> None:
    """Turn a truncated or unfinished recording into a valid one; report what was lost."""
    from rich.console import Console

    from hilrig.recording import recover

    result = recover(file, out)
    console = Console(highlight=False)
    console.print(f"wrote {result.output}")
    console.print(result.summary(), soft_wrap=True)


@app.command("export")
@one_line_errors
def export_command(
    file: _FILE,
    out: Annotated[Path, typer.Option("--out", help="Directory for one table per topic.")],
    fmt: Annotated[
        ExportFormat, typer.Option("--format", help="Table format.")
    ] = ExportFormat.PARQUET,
) -> None:
    """Write one Parquet or CSV table per topic (and metadata.json) into --out."""
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
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    for path in written:
        console.print(f"wrote {path}")
    _problems(Console(stderr=True), problems)
