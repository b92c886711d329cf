"""``hilrig study``: a folder of sessions as a study (catalogue, exclusions, simulation)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import Group, app

if TYPE_CHECKING:
    import pandas as pd
    from rich.console import Console
    from rich.table import Table

study_app = typer.Typer(
    name="study",
    cls=Group,
    help="A folder of recorded sessions as one study: its catalogue, exclusions and a synthetic"
    " study on the emulated rig (docs/study.md).",
    no_args_is_help=True,
)
app.add_typer(study_app)

Folder = Annotated[
    Path,
    typer.Argument(
        metavar="DIR", help="The study's folder of recordings (*.mcap, in sub-folders too)."
    ),
]
#: The catalogue's columns ``study list`` shows unless told otherwise.
SHOWN = (
    "session",
    "subject",
    "condition",
    "scenario",
    "duration_s",
    "collisions",
    "flags",
    "excluded",
)


@study_app.command("index")
def index_command(root: Folder) -> None:
    """Index the folder: read every new or changed recording's metadata into the catalogue
    (DIR/.hilrig-study/), then summarise it."""
    from hilrig.study.catalogue import index, sessions

    console = _console()
    began = time.perf_counter()
    files, read = index(root)
    catalogue = sessions(files)
    took = time.perf_counter() - began
    console.print(
        f"{len(catalogue)} sessions in {len(files)} files: {read} read, "
        f"{len(files) - read} unchanged ({took:.2f} s)"
    )
    _summary(console, catalogue)


@study_app.command("list")
def list_command(
    root: Folder,
    where: Annotated[
        str | None,
        typer.Option(
            help="Only the sessions for which this pandas query holds, over the catalogue's "
            "columns and each scenario setting, e.g. \"controller == 'adaptive' and "
            'stiffness_n_m > 500" or "flags != \'\'".',
        ),
    ] = None,
    columns: Annotated[
        str | None,
        typer.Option(help=f"Comma-separated columns to show (default: {','.join(SHOWN)})."),
    ] = None,
) -> None:
    """List the study's sessions (the folder is indexed first: only new or changed files are
    read), with quality flags and exclusions."""
    from hilrig.study.catalogue import index, sessions, settings_columns
    from hilrig.study.study_file import read_study

    console = _console()
    catalogue = sessions(index(root)[0])
    study = read_study(root)
    whole = {e.session: e.reason for e in study.exclusions if e.event is None}
    parts: dict[str, list[str]] = {}
    for e in study.exclusions:
        if e.event is not None:
            parts.setdefault(e.session, []).append(f"event {e.event}: {e.reason}")
    catalogue["excluded"] = [
        whole.get(s) or "; ".join(parts.get(s, [])) for s in catalogue["session"]
    ]
    frame = settings_columns(catalogue)
    if where:
        frame = _query(frame, where)
    shown = [c.strip() for c in columns.split(",")] if columns else list(SHOWN)
    unknown = [c for c in shown if c not in frame.columns]
    if unknown:
        raise typer.BadParameter(
            f"no column {unknown[0]!r}; columns: {', '.join(frame.columns)}", param_hint="--columns"
        )
    console.print(_table(frame[shown], f"{len(frame)} of {len(catalogue)} sessions"))


@study_app.command("exclude")
def exclude_command(
    root: Folder,
    session: Annotated[str, typer.Argument(help="The session id (hilrig study list).")],
    reason: Annotated[
        str, typer.Option(help="Why, in one line (kept in study.toml and the report).")
    ],
    event: Annotated[
        list[int] | None,
        typer.Option(
            help="Exclude only this event of the session (its number in hilrig analyze's "
            "events table); repeat for several."
        ),
    ] = None,
) -> None:
    """Leave a session, or some of its events, out of the study, with the reason: written to
    DIR/study.toml; the recording is not touched."""
    from hilrig.errors import StudyError
    from hilrig.study.catalogue import index, sessions, twins
    from hilrig.study.study_file import exclude, read_study, write_study

    catalogue = sessions(index(root)[0])
    claimed = twins(catalogue, session)
    if claimed:
        raise StudyError(
            f"{session!r} is claimed by {len(claimed)} sessions of {root}: name one as "
            f"{' or '.join(claimed)}"
        )
    if session not in set(catalogue["session"]):
        raise StudyError(f"{session!r} is not a session of {root} (hilrig study list {root})")
    written = write_study(root, exclude(read_study(root), session, reason, event or ()))
    what = session if not event else f"{session} events {', '.join(map(str, event))}"
    _console().print(f"excluded {what}: {reason.strip()} ({written})", markup=False)


@study_app.command("include")
def include_command(
    root: Folder,
    session: Annotated[str, typer.Argument(help="The session id.")],
    event: Annotated[
        list[int] | None,
        typer.Option(help="Take back only this event's exclusion; repeat for several."),
    ] = None,
) -> None:
    """Take back exclusions of a session (all of them, or those of --event) from study.toml."""
    from hilrig.study.study_file import include, read_study, write_study

    written = write_study(root, include(read_study(root), session, event or ()))
    _console().print(f"included {session} again ({written})", markup=False)


def _console() -> Console:
    from rich.console import Console

    console = Console(highlight=False)
    return console if console.is_terminal else Console(highlight=False, width=200)


def _query(frame: pd.DataFrame, where: str) -> pd.DataFrame:
    from hilrig.errors import StudyError

    try:
        chosen = frame.query(where, engine="python")
    except Exception as err:  # pandas raises many kinds for a bad expression
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise StudyError(f"--where {where!r}: {message}") from None
    if not isinstance(chosen, type(frame)):
        raise StudyError(f"--where {where!r}: not a condition on the sessions")
    return chosen


def _table(frame: pd.DataFrame, title: str) -> Table:
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=title, title_justify="left")
    for column in frame.columns:
        numeric = frame[column].dtype.kind in "iuf"
        table.add_column(str(column), justify="right" if numeric else "left")
    for row in frame.itertuples(index=False):
        table.add_row(*(escape(_cell(v)) for v in row))
    return table


def _cell(value: object) -> str:
    if isinstance(value, float):
        return "" if value != value else f"{value:.4g}"
    return str(value)


def _summary(console: Console, catalogue: pd.DataFrame) -> None:
    """Sessions per condition and subject, and the flagged ones."""
    from rich.markup import escape

    readable = catalogue[catalogue["subject"] != ""]
    if not readable.empty:
        counts = readable.pivot_table(
            index="subject", columns="condition", values="session", aggfunc="count", fill_value=0
        ).reset_index()
        console.print(_table(counts, "sessions"))
    flagged = catalogue[catalogue["flags"] != ""]
    for session, flags in flagged[["session", "flags"]].itertuples(index=False):
        console.print(f"[yellow]flagged[/] {escape(str(session))}: {flags}")
