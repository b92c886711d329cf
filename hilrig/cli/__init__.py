"""``hilrig`` command line: thin commands that parse options and call library functions.

Importing it is light (``hilrig --help`` answers at once): each command imports what it needs
when it runs, and the signatures take their types from light modules (:mod:`.options`).
Expected failures (HilrigError) print one line to stderr and exit 2; nothing else is caught.
"""

import sys

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
from hilrig.cli.errors import ERROR_EXIT, print_error
from hilrig.errors import HilrigError

__all__ = ["app", "main"]


def main() -> None:
    """Entry point of the ``hilrig`` script."""
    try:
        app()
    except HilrigError as err:
        print_error(err)
        sys.exit(ERROR_EXIT)
