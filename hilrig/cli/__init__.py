"""``hilrig`` command line: thin commands that parse options and call library functions.

Importing it is light (``hilrig --help`` answers at once): each command imports what it needs
when it runs, and the signatures take their types from light modules (:mod:`.options`).
Every failure is one line on stderr (:mod:`.errors`): expected ones (HilrigError, a mistake in
the command line) exit 2, anything else is reported as a bug and exits 3, Ctrl-C exits 130;
``hilrig --debug COMMAND`` shows the full traceback.
"""

import sys
import warnings
from collections.abc import Sequence

import typer
from typer._click.exceptions import ClickException, NoArgsIsHelpError, UsageError
from typer.main import get_command

from hilrig.cli import (  # noqa: F401  (register their commands)
    analyze,
    demo,
    doctor,
    paper,
    record,
    recording,
    replay,
    report,
    rig,
    study,
    study_simulate,
    sweep,
    view,
)
from hilrig.cli.app import app
from hilrig.cli.errors import (
    BUG_EXIT,
    ERROR_EXIT,
    INTERRUPT_EXIT,
    SETTINGS,
    disk_error,
    print_bug,
    print_error,
    print_interrupted,
    print_usage_error,
    show_warning,
)
from hilrig.errors import HilrigError, StoppedWaitingError

__all__ = ["app", "main", "run"]


def main() -> None:
    """Entry point of the ``hilrig`` script."""
    sys.exit(run(sys.argv[1:]))


def run(args: Sequence[str]) -> int:
    """Run the command line ``args`` (without the program's name); its exit status."""
    SETTINGS.debug = False  # until the app's callback reads --debug
    shown_by = warnings.showwarning
    warnings.showwarning = show_warning
    try:
        return _run(args)
    finally:
        warnings.showwarning = shown_by


def _run(args: Sequence[str]) -> int:
    try:
        status = get_command(app).main(list(args), prog_name="hilrig", standalone_mode=False)
    except StoppedWaitingError as err:  # Ctrl-C (or SIGTERM) before the session began
        print_interrupted(str(err))
        return INTERRUPT_EXIT
    except HilrigError as err:
        print_error(err)
        return ERROR_EXIT
    except NoArgsIsHelpError as err:  # ``hilrig`` alone shows its help
        err.show()
        return err.exit_code
    except UsageError as err:
        print_usage_error(err.format_message(), err.ctx.command_path if err.ctx else None)
        return err.exit_code
    except ClickException as err:
        print_usage_error(err.format_message(), None)
        return err.exit_code
    except typer.Abort:  # end of input where a prompt read it
        print_usage_error("aborted", None)
        return 1
    except KeyboardInterrupt:
        print_interrupted()
        return INTERRUPT_EXIT
    except Exception as err:
        disk = disk_error(err)
        if disk is not None:
            print_error(disk)
            return ERROR_EXIT
        print_bug(err)
        return BUG_EXIT
    # typer turns a KeyboardInterrupt in a command into exit status 130 (no command returns it)
    if status == INTERRUPT_EXIT:
        print_interrupted()
    return status if isinstance(status, int) else 0
