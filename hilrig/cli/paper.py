"""``hilrig paper``: the paper's simulation experiments, tables and figures."""

from collections.abc import Iterable
from pathlib import Path
from typing import Annotated

import typer

from hilrig.cli.app import app

DEFAULT_OUT = Path("build/paper")
#: Said after an output that is already there.
ELSEWHERE = "choose another --out, or move the earlier outputs away"


@app.command()
def paper(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help="Directory for the tables (Markdown, CSV) and PNGs (made if needed; files "
            "already there are never overwritten).",
        ),
    ] = DEFAULT_OUT,
) -> None:
    """Run the paper's simulations (sections 2.1 and 3.4) and compare with its numbers."""
    from rich.console import Console

    from hilrig.errors import DiskError, OutputError
    from hilrig.paper.report import rich_table
    from hilrig.paper.reproduce import output_names, reproduce

    try:
        check_outputs(out / name for name in output_names())
        reproduction = reproduce(out)
    except DiskError:  # says what to do itself
        raise
    except OutputError as err:
        err.add_note(ELSEWHERE)
        raise
    console = Console(markup=False, highlight=False)
    for section in reproduction.sections:
        console.print(rich_table(section, console.width))
    console.print(f"Wrote {len(reproduction.files)} files:")
    for path in reproduction.files:
        console.print(f"  {path}", soft_wrap=True)


def check_outputs(paths: Iterable[Path]) -> None:
    """Raise OutputError (one line) unless each of ``paths`` can be written as a new file, its
    missing folders made: the nearest existing folder above it must be a writable folder."""
    import os

    from hilrig.errors import OutputError
    from hilrig.outputs import check_new_file, nearest_existing

    for path in paths:
        above = nearest_existing(path.parent)
        if not above.is_dir():
            raise OutputError(f"{path}: {above} is not a folder")
        if not os.access(above, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: folder {above} is not writable")
        check_new_file(path, create_folder=True)
