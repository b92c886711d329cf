"""``hilrig`` command line: thin commands that parse options and call library functions.

Expected failures (HilrigError) print one line to stderr and exit 2; nothing else is caught.
"""

import sys

from rich.console import Console
from rich.text import Text

from hilrig.cli import (  # noqa: F401  (register their commands)
    analyze,
    demo,
    paper,
    record,
    recording,
    replay,
    rig,
    view,
)
from hilrig.cli.app import app
from hilrig.errors import HilrigError

__all__ = ["app", "main"]


def main() -> None:
    """Entry point of the ``hilrig`` script."""
    try:
        app()
    except HilrigError as err:
        # one line whatever the width, and the message is text, never rich markup
        line = Text("error: ", style="bold red").append(str(err))
        Console(stderr=True, soft_wrap=True).print(line, highlight=False)
        sys.exit(2)
