"""Long sessions split into numbered files (:class:`~.writer.SessionWriter`'s ``split``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class SplitPolicy:
    """Start a new numbered file once the current one spans ``max_duration_s`` of log time or
    holds ``max_bytes``; either may be None. Files are ``<stem>_000.mcap``, ``<stem>_001.mcap``..
    """

    max_duration_s: float | None = None
    max_bytes: int | None = None


def part_path(path: Path, part: int) -> Path:
    """The file of split part number ``part`` of a session written to ``path``."""
    return path.with_name(f"{path.stem}_{part:03d}{path.suffix}")
