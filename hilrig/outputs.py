"""One way to write outputs: refuse what exists, write beside it under a temporary name, move
into place only when complete, and leave nothing behind after a failure.

Every command that writes files goes through :func:`new_files`::

    with new_files(table_path, report_path, overwrite=False) as (table_tmp, report_tmp):
        write_table(table_tmp)
        write_report(report_tmp)
    # both are in place now, or neither is (and no temporary is left)

All paths are checked before any work starts (folder exists and is writable, nothing at the
path unless ``overwrite``, never a folder or a device node); the temporaries sit in the same
folders (hidden, same suffix), so the final move is a rename on one file system. Without
``overwrite`` a file is moved in with ``link`` + ``unlink``, which fails rather than replaces
if someone created the path meanwhile; with it, ``os.replace`` (atomic, one file at a time). If
a move fails, the new files already moved are taken back out, so a failure leaves the folders as
they were (with ``overwrite``, files already replaced stay replaced).

A disk that cannot take the outputs (full, over quota, past its largest file, failing: see
:data:`DISK_ERRORS`) is an expected failure: whatever the writer raised (an OSError, or a
library's error that carries it as a cause or in its text), :func:`new_files` removes the
temporaries and raises :class:`DiskError`, one line saying what could not be written, where,
that nothing was written, and what to do.
"""

from __future__ import annotations

import errno
import os
import re
import secrets
import stat
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path

from hilrig.errors import DiskError, OutputError

#: The errors of a disk that cannot take an output: what each means, and what to do.
DISK_ERRORS: dict[int, tuple[str, str]] = {
    errno.ENOSPC: ("the disk is full", "free space and run again"),
    errno.EDQUOT: ("the disk quota is exceeded", "free space (or raise the quota) and run again"),
    errno.EFBIG: (
        "a file is larger than allowed (by its file system, or the process's limit)",
        "write it elsewhere (or raise the limit) and run again",
    ),
    errno.EIO: ("the disk failed to write (I/O error)", "check the disk and run again"),
}
#: An error number in a library's message: Python's ``[Errno 28]``, Arrow's ``[errno 28]``,
#: Rust's ``(os error 28)`` (Rerun).
_ERRNO_TEXT = re.compile(r"(?:\berrno|\bos error)\s*(\d+)", re.IGNORECASE)


def nearest_existing(path: Path) -> Path:
    """``path`` if it exists, else the nearest of its parents that does (at worst the root)."""
    return next(p for p in (path, *path.parents) if p.exists() or p == p.parent)


def check_new_file(path: Path, *, overwrite: bool = False, create_folder: bool = False) -> None:
    """Raise :class:`OutputError` unless ``path`` can be written as a new (or, with
    ``overwrite``, replaced regular) file."""
    folder = path.parent
    if path.name in ("", ".", ".."):
        raise OutputError(f"{path}: not a file name")
    if folder.exists():
        if not folder.is_dir():
            raise OutputError(f"{path}: {folder} is not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: folder {folder} is not writable")
    else:
        existing = nearest_existing(folder)
        if not existing.is_dir():
            raise OutputError(f"{path}: {existing} is not a folder")
        if create_folder and not os.access(existing, os.W_OK | os.X_OK):
            raise OutputError(f"{path}: folder {existing} is not writable")
        if not create_folder:
            raise OutputError(f"{path}: folder {folder} does not exist")
        return
    try:
        mode = path.lstat().st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISREG(mode):
        raise OutputError(f"{path}: exists and is not a regular file; refusing to write there")
    if not overwrite:
        raise OutputError(f"{path}: already exists; refusing to overwrite it")


def temporary_beside(path: Path) -> Path:
    """A fresh hidden name in ``path``'s folder with ``path``'s suffix (writers that read it)."""
    return path.with_name(f".{path.stem}.{secrets.token_hex(4)}.partial{path.suffix}")


@contextmanager
def new_files(
    *paths: Path, overwrite: bool = False, create_folders: bool = False
) -> Iterator[tuple[Path, ...]]:
    """Yield a temporary path for each of ``paths``; when the block ends without an error, move
    each into place (all of them or none); after an error, remove the temporaries (and folders
    this call created) and re-raise."""
    finals = [Path(p) for p in paths]
    if len(set(finals)) != len(finals):
        raise OutputError(f"{', '.join(map(str, finals))}: the same output is named twice")
    for final in finals:
        check_new_file(final, overwrite=overwrite, create_folder=create_folders)
    made_folders = _make_folders(finals) if create_folders else []
    temporaries = tuple(temporary_beside(final) for final in finals)
    moved: list[Path] = []
    try:
        yield temporaries
        for temporary, final in zip(temporaries, finals, strict=True):
            if not temporary.exists():
                raise OutputError(f"{final}: nothing was written")
            _move_into_place(temporary, final, overwrite=overwrite)
            moved.append(final)
    except BaseException as error:
        for final in moved if not overwrite else []:
            final.unlink(missing_ok=True)
        for temporary in temporaries:
            temporary.unlink(missing_ok=True)
        for folder in reversed(made_folders):
            _remove_if_empty(folder)
        code = None if isinstance(error, DiskError) else disk_errno(error)
        if code is None:
            raise
        replaced = len(moved) if overwrite else 0
        raise DiskError(disk_message(code, finals, replaced=replaced)) from error


def disk_errno(error: BaseException) -> int | None:
    """The :data:`DISK_ERRORS` number behind ``error``: an OSError's in its chain of causes, or
    one its messages name (libraries that carry it as text); None if there is none."""
    chain: list[BaseException] = []
    link: BaseException | None = error
    while link is not None and link not in chain:
        chain.append(link)
        link = link.__cause__ or link.__context__
    for link in chain:
        if isinstance(link, OSError) and link.errno in DISK_ERRORS:
            return link.errno
    for link in chain:
        text = str(link)
        for number in _ERRNO_TEXT.findall(text):
            if int(number) in DISK_ERRORS:
                return int(number)
        for code in DISK_ERRORS:
            if os.strerror(code) in text:
                return code
    return None


def disk_message(code: int, paths: Sequence[Path], *, replaced: int = 0) -> str:
    """One line for a disk error ``code`` (:data:`DISK_ERRORS`) that stopped writing ``paths``:
    what, where, what is left (``replaced`` outputs were already replaced) and what to do."""
    meaning, remedy = DISK_ERRORS[code]
    what = paths[0].name if len(paths) == 1 else f"{len(paths)} files"
    where = os.path.commonpath([str(path.parent) for path in paths])
    left = "nothing was written" if not replaced else f"{replaced} of them already replaced"
    return f"{meaning}: could not write {what} ({where}): {left}; {remedy}"


def _move_into_place(temporary: Path, final: Path, *, overwrite: bool) -> None:
    if overwrite:
        os.replace(temporary, final)
        return
    try:
        os.link(temporary, final)
    except FileExistsError:
        raise OutputError(f"{final}: appeared while writing; refusing to overwrite it") from None
    except OSError as error:
        raise OutputError(f"{final}: cannot be moved into place ({error.strerror})") from None
    temporary.unlink()


def _make_folders(finals: list[Path]) -> list[Path]:
    """Create the missing folders of ``finals``; the ones created, outermost first."""
    made: list[Path] = []
    for final in finals:
        missing = [p for p in (final.parent, *final.parent.parents) if not p.exists()]
        for folder in reversed(missing):
            try:
                folder.mkdir()
            except FileExistsError:
                continue
            except OSError as error:
                for created in reversed(made):
                    _remove_if_empty(created)
                raise OutputError(
                    f"{final}: folder {folder} cannot be made ({error.strerror})"
                ) from None
            made.append(folder)
    return made


def _remove_if_empty(folder: Path) -> None:
    with suppress(OSError):
        folder.rmdir()
