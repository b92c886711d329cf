"""One way to fail: every failure of a command is exactly one line on stderr, never wrapped and
never read as markup, with an exit status that says what kind it was.

- an expected failure (HilrigError, a mistake in the command line): ``error: ...``, exit 2;
  a disk that refused a write (full, over quota, failing) is one too, wherever it happened
  (:func:`disk_error`);
- anything else is a bug: ``error: unexpected <type>: <message>`` asking for a report, exit 3;
- Ctrl-C outside a session, or while a session waits for the machine's other session:
  ``interrupted: ...``, exit 130;
- a warning (e.g. a RecordingWarning about a damaged file): ``warning: ...``.

``hilrig --debug COMMAND`` prints the full traceback before the line (:data:`SETTINGS`).
"""

from __future__ import annotations

import functools
import re
import traceback
from collections.abc import Callable
from typing import TYPE_CHECKING, ParamSpec, TextIO, TypeVar

import typer

from hilrig.errors import DiskError, HilrigError

if TYPE_CHECKING:
    from rich.console import Console

P = ParamSpec("P")
R = TypeVar("R")
#: Exit status of an expected failure (and of a mistake in the command line).
ERROR_EXIT = 2
#: Exit status of a bug: an exception hilrig did not expect.
BUG_EXIT = 3
#: Exit status after Ctrl-C (128 + SIGINT), as shells report it.
INTERRUPT_EXIT = 130


class Settings:
    """The global options (``hilrig --debug``), set by the app's callback."""

    debug = False


SETTINGS = Settings()


def one_line(text: str) -> str:
    """``text`` with its line breaks and runs of white space made single spaces."""
    return " ".join(text.split())


def _stderr() -> Console:
    from rich.console import Console

    return Console(stderr=True, soft_wrap=True, markup=False, highlight=False)


def print_line(label: str, style: str, text: str) -> None:
    """``<label>: <text>`` on stderr as one line (``text`` is shown as given: no markup)."""
    from rich.text import Text

    _stderr().print(Text.assemble((f"{label}: ", style), one_line(text)))


def message_of(err: BaseException) -> str:
    """``err``'s message and its notes (e.g. where a session's recording was kept), one line."""
    notes = getattr(err, "__notes__", [])
    return "; ".join([one_line(str(err)) or "(no message)", *map(one_line, notes)])


def print_error(err: HilrigError) -> None:
    """``error: <message>`` on stderr, one line whatever the terminal's width."""
    if SETTINGS.debug:
        traceback.print_exception(err)
    print_line("error", "bold red", message_of(err))


def print_usage_error(message: str, command: str | None) -> None:
    """A mistake in the command line (unknown option, bad value) as one ``error:`` line."""
    message = re.sub(r"Value error, ", "", one_line(message))  # typer's pydantic prefix
    where = f" (see {command} --help)" if command else ""
    print_line("error", "bold red", f"{message}{where}")


def disk_error(err: BaseException) -> DiskError | None:
    """``err`` as a one-line :class:`DiskError` if a disk refused a write behind it (a write
    outside :func:`hilrig.outputs.new_files`, which raises DiskError itself); else None."""
    from hilrig.outputs import DISK_ERRORS, disk_errno

    code = disk_errno(err)
    if code is None:
        return None
    meaning, remedy = DISK_ERRORS[code]
    names = [e.filename for e in (err, err.__cause__, err.__context__) if isinstance(e, OSError)]
    where = next((f" {name}" for name in names if name), "")
    disk = DiskError(f"{meaning}: could not write{where or ' an output'}; {remedy}")
    disk.__cause__ = err  # hilrig --debug shows the write that failed
    return disk


def print_bug(err: BaseException) -> None:
    """An unexpected exception: one line naming it and asking for a bug report (the full
    traceback first with ``--debug``)."""
    if SETTINGS.debug:
        traceback.print_exception(err)
        hint = "please report it with the traceback above"
    else:
        hint = "please report it; run again with hilrig --debug ... for the full traceback"
    print_line(
        "error",
        "bold red",
        f"unexpected {type(err).__name__}: {message_of(err)}. This is a bug in hilrig: {hint}",
    )


def print_waiting(text: str) -> None:
    """``waiting: <text>`` on stderr (a session waiting for the machine's other session)."""
    print_line("waiting", "yellow", text)


def print_warning(text: str) -> None:
    """``warning: <text>`` on stderr (e.g. a setting of the machine that costs a session)."""
    print_line("warning", "yellow", text)


def print_interrupted(text: str = "stopped by Ctrl-C") -> None:
    """``interrupted: <text>`` on stderr."""
    print_line("interrupted", "bold red", text)


def show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """:func:`warnings.showwarning` for the command line: ``warning: <message>``, one line."""
    print_warning(str(message))


def interrupted_by(err: BaseException) -> bool:
    """Whether ``err`` is or wraps a Ctrl-C (Python wraps one raised in ``__set_name__`` in a
    RuntimeError; a caller may have turned that into a HilrigError)."""
    seen: set[int] = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


def one_line_errors(command: Callable[P, R]) -> Callable[P, R]:
    """``command`` with its expected failures printed by :func:`print_error` (exit 2), for
    callers of the typer app that bypass :func:`hilrig.cli.main` (tests)."""

    @functools.wraps(command)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return command(*args, **kwargs)
        except HilrigError as err:
            if interrupted_by(err):
                raise KeyboardInterrupt from err
            print_error(err)
            raise typer.Exit(ERROR_EXIT) from err
        except Exception as err:
            if interrupted_by(err):
                raise KeyboardInterrupt from err
            disk = disk_error(err)
            if disk is None:
                raise
            print_error(disk)
            raise typer.Exit(ERROR_EXIT) from err

    return run
