"""Expected failures (HilrigError) as exactly one line on stderr, never wrapped and never read
as markup, and exit status 2; anything else is a bug and keeps its traceback."""

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import typer

from hilrig.errors import HilrigError

P = ParamSpec("P")
R = TypeVar("R")
#: Exit status of an expected failure.
ERROR_EXIT = 2


def print_error(err: HilrigError) -> None:
    """``error: <message>`` on stderr, one line whatever the terminal's width."""
    from rich.console import Console
    from rich.text import Text

    line = Text.assemble(("error: ", "bold red"), str(err))
    Console(stderr=True, soft_wrap=True).print(line, highlight=False)


def one_line_errors(command: Callable[P, R]) -> Callable[P, R]:
    """``command`` with its expected failures printed by :func:`print_error` (exit 2), for
    callers of the typer app that bypass :func:`hilrig.cli.main` (tests)."""

    @functools.wraps(command)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return command(*args, **kwargs)
        except HilrigError as err:
            print_error(err)
            raise typer.Exit(ERROR_EXIT) from err

    return run
