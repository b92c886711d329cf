"""``hilrig`` command line: thin commands that parse options and call library functions.

Importing it is light (``hilrig --help`` answers at once): each command imports what it needs
when it runs, and the signatures take their types from light modules (:mod:`.options`).
Every failure is one line on stderr (:mod:`.errors`): expected ones (HilrigError, a mistake in
the command line) exit 2, anything else is reported as a bug and exits 3, Ctrl-C exits 130;
``hilrig --debug COMMAND`` shows the full traceback.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence

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
    interrupted_by,
    print_bug,
    print_error,
    print_interrupted,
    print_usage_error,
    show_warning,
)
from hilrig.errors import HilrigError, StoppedWaitingError

__all__ = ["app", "main", "run"]

#: Seconds before a Ctrl-C caught where Python cannot raise it is sent again.
AGAIN_S = 0.01


def main() -> None:
    """Entry point of the ``hilrig`` script."""
    sys.exit(run(sys.argv[1:]))


def run(args: Sequence[str]) -> int:
    """Run the command line ``args`` (without the program's name); its exit status."""
    SETTINGS.debug = False  # until the app's callback reads --debug
    shown_by, unraisable_by = warnings.showwarning, sys.unraisablehook
    warnings.showwarning = show_warning
    sys.unraisablehook = _unraisable(unraisable_by)
    try:
        return _run(args)
    finally:
        warnings.showwarning, sys.unraisablehook = shown_by, unraisable_by


def _unraisable(
    shown_by: Callable[[sys.UnraisableHookArgs], object],
) -> Callable[[sys.UnraisableHookArgs], None]:
    """A hook for exceptions Python cannot raise (in ``__del__``, a weakref callback): a Ctrl-C
    caught there is delivered again rather than lost, so the command still ends on the first
    one; anything else is shown as Python shows it."""

    def hook(unraisable: sys.UnraisableHookArgs) -> None:
        if unraisable.exc_type is KeyboardInterrupt:
            _interrupt_again()
        else:
            shown_by(unraisable)

    return hook


def _interrupt_again() -> None:
    """SIGINT to this process once more, sent by another thread a moment later: its handler
    then runs in the code that follows the hook, not in the hook (where its exception would be
    lost too). Should it come before the hook returned, it is sent again."""
    while True:
        try:
            threading.Timer(AGAIN_S, os.kill, (os.getpid(), signal.SIGINT)).start()
        except KeyboardInterrupt:  # it came here: send another
            continue
        return


def _run(args: Sequence[str]) -> int:
    try:
        status = get_command(app).main(list(args), prog_name="hilrig", standalone_mode=False)
    except StoppedWaitingError as err:  # Ctrl-C (or SIGTERM) before the session began
        print_interrupted(str(err))
        return INTERRUPT_EXIT
    except HilrigError as err:
        if interrupted_by(err):
            print_interrupted()
            return INTERRUPT_EXIT
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
        if interrupted_by(err):
            print_interrupted()
            return INTERRUPT_EXIT
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
