"""A transient progress bar on the terminal, one task per phase of a long job."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeRemainingColumn,
)

#: What each phase of a replay is called on the bar.
PHASES = {
    "load": "reading chunks",
    "replay": "replaying ticks",
    "write": "writing ticks",
    "fit": "fitting the world",
    "closed": "closed-loop runs",
    "indexing": "reading new recordings",
    "analysing": "analysing sessions",
    "figures": "drawing figures",
}
#: Least seconds between two redraws.
REDRAW_S = 0.1


@contextmanager
def phase_bar(console: Console, *, enabled: bool) -> Iterator[Phases | None]:
    """A bar on ``console`` whose tasks :class:`Phases` feeds (None when not ``enabled``),
    redrawn by the callbacks rather than by rich's refresh thread: a replay may fork a process
    pool, and a fork must not happen while another thread holds the terminal's lock."""
    if not enabled:
        yield None
        return
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
    with Progress(
        *columns, TimeRemainingColumn(), console=console, transient=True, auto_refresh=False
    ) as bar:
        yield Phases(bar)


class Phases:
    """``progress(phase, done, total)`` onto one task of ``bar`` per phase."""

    def __init__(self, bar: Progress) -> None:
        self.bar = bar
        self.tasks: dict[str, TaskID] = {}
        self.drawn = 0.0

    def __call__(self, phase: str, done: int, total: int) -> None:
        task = self.tasks.get(phase)
        if task is None:
            task = self.tasks[phase] = self.bar.add_task(PHASES.get(phase, phase), total=total)
        now = time.monotonic()
        redraw = done >= total or now - self.drawn >= REDRAW_S
        self.bar.update(task, completed=done, total=total, refresh=redraw)
        if redraw:
            self.drawn = now
