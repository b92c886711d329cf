"""The typer application every ``hilrig`` command registers on."""

import typer
from typer._click import Command, Context
from typer.core import TyperGroup, TyperOption

from hilrig.cli.errors import SETTINGS


class Group(TyperGroup):
    """A typer group whose ``--help``, when not given, reads False rather than None, and whose
    command list shows each command's first paragraph as one line of prose.

    Typer coerces every non-bool parameter value through a pydantic adapter built on first use;
    a group's unset ``--help`` (None) made ``hilrig COMMAND --help`` load pydantic for it.
    Typer 0.29's command list keeps a docstring's line breaks (its command pages join them).
    """

    def get_command(self, ctx: Context, cmd_name: str) -> Command | None:
        command = super().get_command(ctx, cmd_name)
        if command is not None and command.short_help is None and command.help:
            first_paragraph = command.help.strip().split("\n\n")[0]
            command.short_help = " ".join(first_paragraph.split())
        return command

    def get_help_option(self, ctx: Context) -> TyperOption | None:
        option = super().get_help_option(ctx)
        if option is not None:
            option.default = False
        return option


app = typer.Typer(
    name="hilrig",
    cls=Group,
    help="Hardware-in-the-loop experiments on collaborative-robot collision response.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    if value:
        from hilrig import __version__

        typer.echo(f"hilrig {__version__}")
        raise typer.Exit()


@app.callback()
def root(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version."
    ),
    debug: bool = typer.Option(
        False,
        "--debug",
        help="On any failure, print the full traceback before the one-line error (for a bug "
        "report).",
    ),
) -> None:
    """Hardware-in-the-loop experiments on collaborative-robot collision response."""
    SETTINGS.debug = debug
