"""The typer application every ``hilrig`` command registers on."""

import typer

app = typer.Typer(
    name="hilrig",
    help="Hardware-in-the-loop experiments on collaborative-robot collision response.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
