"""numba for hilrig's kernels: ``njit``, with the compiled-code cache keyed on their sources.

Numba keys a cached function (``cache=True``) on its own file's time stamp and size, not on the
files whose functions and constants it compiles in: after a change to ``hilrig/control/axis.py``
a checkout with a cache kept running the tick (``hilrig/tick/kernel.py``) and the control kernel
(``kernel.py``) with the old ``axis.py``. So every hilrig module with compiled code takes
``njit`` from here, and importing this module first points numba's cache
(``numba.config.CACHE_DIR``) at a folder named after a hash of the source of those modules and
of every hilrig module they import, transitively (a package imported: all of its modules). Any
change to any of them compiles everything afresh, once. The folders are under
``$NUMBA_CACHE_DIR/hilrig`` if that is set, else ``$XDG_CACHE_HOME/hilrig/numba`` (``~/.cache``);
folders unused for :data:`KEEP_DAYS` days are removed.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import tempfile
import time
from pathlib import Path

import numba
from numba import njit

__all__ = ["cache_folder", "njit", "source_key", "sources"]

PACKAGE = Path(__file__).resolve().parent
KEEP_DAYS = 7
_IMPORT = re.compile(r"^\s*(?:from|import)\s+(hilrig(?:\.\w+)*)", re.MULTILINE)
_COMPILES = re.compile(r"^\s*(?:from|import)\s+(?:numba\b|hilrig\.compiled\b)", re.MULTILINE)


def sources(package: Path = PACKAGE) -> list[Path]:
    """The modules of ``package`` with compiled code (they import numba or this module) and
    every module of it they import, transitively; sorted."""
    return sorted(_compiled_in(package))


def _compiled_in(package: Path) -> dict[Path, str]:
    """:func:`sources` with their texts."""
    texts = {path: path.read_text(encoding="utf-8") for path in package.rglob("*.py")}
    todo = [path for path, text in texts.items() if _COMPILES.search(text)]
    found: dict[Path, str] = {}
    while todo:
        path = todo.pop()
        if path in found:
            continue
        found[path] = texts[path]
        for name in _IMPORT.findall(texts[path]):
            todo += _modules(package, name.split(".")[1:], texts)
    return found


def _modules(package: Path, parts: list[str], texts: dict[Path, str]) -> list[Path]:
    """The files of module ``parts`` (under ``package``): one file, or a package's every file."""
    where = package.joinpath(*parts)
    if where.with_suffix(".py") in texts:
        return [where.with_suffix(".py")]
    return [path for path in texts if path.is_relative_to(where)]


def source_key(package: Path = PACKAGE) -> str:
    """A hash of the names and texts of :func:`sources` (16 hex digits)."""
    digest = hashlib.sha256()
    for path, text in sorted(_compiled_in(package).items()):
        digest.update(str(path.relative_to(package)).encode() + b"\0")
        digest.update(text.encode() + b"\0")
    return digest.hexdigest()[:16]


def cache_folder(key: str) -> Path:
    """Where the kernels compiled from sources of ``key`` are kept."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given) / "hilrig" / key
    home = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(home) / "hilrig" / "numba" / key


def _use(key: str) -> None:
    """Point numba's cache at :func:`cache_folder` (or, where that cannot be made, one in the
    temporary folder; else leave numba's own); remove its siblings (other keys' folders, in a
    folder of hilrig's own) unused for KEEP_DAYS days."""
    for folder in (cache_folder(key), Path(tempfile.gettempdir()) / "hilrig-numba" / key):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            os.utime(folder)
        except OSError:
            continue
        old = time.time() - KEEP_DAYS * 86400
        for other in folder.parent.iterdir():
            with contextlib.suppress(OSError):
                if other != folder and other.is_dir() and other.stat().st_mtime < old:
                    shutil.rmtree(other, ignore_errors=True)
        numba.config.CACHE_DIR = str(folder)  # type: ignore[attr-defined]  # set at run time
        return


_use(source_key())
