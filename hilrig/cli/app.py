"""The typer application every ``hilrig`` command registers on."""

import typer

from hilrig import __version__

app = typer.Typer(
    name="hilrig",
    help="Hardware-in-the-loop experiments on collaborative-robot collision response.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"hilrig {__version__}")
        raise typer.Exit()


@app.callback()
def root(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version."
    ),
) -> None:
    """Hardware-in-the-loop experiments on collaborative-robot collision response."""
