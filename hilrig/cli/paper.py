"""``hilrig paper``: the paper's simulation experiments, tables and figures."""

from pathlib import Path
from typing import Annotated

import typer

from hilrig.cli.app import app

DEFAULT_OUT = Path("build/paper")


@app.command()
def paper(
    out: Annotated[
        Path, typer.Option("--out", help="Directory for the tables (Markdown, CSV) and PNGs.")
    ] = DEFAULT_OUT,
) -> None:
    """Run the paper's simulations (sections 2.1 and 3.4) and compare with its numbers."""
    from rich.console import Console

    from hilrig.paper.report import rich_table
    from hilrig.paper.reproduce import reproduce

    reproduction = reproduce(out)
    console = Console()
    for section in reproduction.sections:
        console.print(rich_table(section))
    console.print(f"Wrote {len(reproduction.files)} files:")
    for path in reproduction.files:
        console.print(f"  {path}", highlight=False)
