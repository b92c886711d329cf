"""Damage found in a file: which record, where, what is wrong with it, and what it costs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hilrig.errors import RecordingError


@dataclass(frozen=True)
class Damage:
    """A damaged part of a file: ``what`` (a record kind, e.g. ``metadata record 'session'``)
    at byte ``offset``, ``end`` (exclusive) when its extent is known, ``detail`` (what is wrong)
    and ``cost`` (what reading the file loses by it; empty when nothing is lost)."""

    what: str
    offset: int
    detail: str
    end: int | None = None
    cost: str = ""

    def line(self, path: Path) -> str:
        """One line for people: file, record, byte offset, what is wrong and what it costs."""
        where = f"bytes {self.offset}-{self.end - 1}" if self.end else f"byte {self.offset}"
        line = f"{path}: {self.what} at {where}: {self.detail}"
        return f"{line}; {self.cost}" if self.cost else line

    def error(self, path: Path) -> RecordingError:
        return RecordingError(self.line(path))
