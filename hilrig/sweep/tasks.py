"""A sweep's tasks: every (input, parameter set) pair (inputs: :mod:`.inputs`), and the
function that runs one.

One task replays one source through one controller spec (:mod:`hilrig.replay`, open or closed
loop), finds the collisions in the force that run met and measures them
(:mod:`hilrig.analysis`), and writes the metrics (and with ``tables`` the result table) as its
partitions of the output (:mod:`.dataset`), less the rows of events a study excludes
(matched by group and time window). A task depends on nothing but its input and spec,
so it gives the same rows wherever and however often it runs; one already done is not redone.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from hilrig.analysis import Source, SourceKind, analyze, metrics_frame, runs_from_frame
from hilrig.analysis.sources import KNOWN_AXES
from hilrig.errors import DiskError, HilrigError
from hilrig.outputs import disk_errno
from hilrig.replay import ForceTrace
from hilrig.replay.job import Replayed, closed_replay_file, replay_trace
from hilrig.replay.results import INPUT_KEY
from hilrig.replay.specs import ControllerSpec
from hilrig.sweep.dataset import Layout
from hilrig.sweep.inputs import NS_PER_S, ExcludedEvent, Inputs
from hilrig.sweep.memory import ARENA, keep_freed_memory, trace_of
from hilrig.sweep.summary import GroupTally, subject_of, tally

#: Text columns of the metrics rows, stored as strings whatever the rows hold (even none).
TEXT_COLUMNS = ("source", "run", "law", "group", "axis", "body_region", "verdict", "binding")
#: Columns a task adds to analysis's metrics: where the input came from and what was swept.
SWEEP_COLUMNS = ("subject_id", "session_id", "controller", "settings", "input")
#: :func:`warm_up`'s trace: two ticks of zeros on every axis, at 1 kHz.
WARM_UP_DT_S = 0.001


@dataclass(frozen=True)
class Task:
    """One input through one controller spec (less the events a study excludes)."""

    source: str
    path: Path
    spec: ControllerSpec
    closed_loop: bool = False
    excluded: tuple[ExcludedEvent, ...] = ()

    @property
    def run(self) -> str:
        return self.spec.name


@dataclass(frozen=True)
class TaskResult:
    """What one task did: rows written, or why it failed (``error``, one line); ``skipped``
    when its partitions were already in place (a retry of a task that had finished)."""

    source: str
    run: str
    rows: int = 0
    seconds: float = 0.0
    worker: str = ""  # host:pid
    node: str = ""  # the Ray node id (ray engine)
    error: str = ""
    disk_errno: int = 0  # the disk refused its partitions (:data:`hilrig.outputs.DISK_ERRORS`)
    skipped: bool = False
    subject: str = ""  # the source's subject (:func:`.summary.subject_of`)
    tallies: tuple[GroupTally, ...] = ()  # its events, for the sweep's summary


def plan(inputs: Inputs, specs: Sequence[ControllerSpec], *, closed_loop: bool) -> list[Task]:
    """Every (input, spec) task, by input then spec."""
    return [
        Task(item.source, item.path, spec, closed_loop, item.excluded)
        for item in inputs.files
        for spec in specs
    ]


def warm_up(tasks: Sequence[Task]) -> None:
    """Load in this process the compiled kernels that the open-loop tasks' controllers run
    (numba loads each from its cache at its first call: 0.3 s of a fresh worker's first task,
    about the time of a whole task), by replaying two ticks of zeros through every spec: local
    workers forked after it inherit them instead of each loading them again. A spec that
    cannot run is left to its own task to report; closed-loop tasks load theirs themselves."""
    specs = {task.spec.name: task.spec for task in tasks if not task.closed_loop}
    if not specs:
        return
    t_s = np.arange(2, dtype=np.float64) * WARM_UP_DT_S
    force = np.zeros((2, len(KNOWN_AXES)))
    trace = ForceTrace(t_s, force, KNOWN_AXES, "warm-up", WARM_UP_DT_S)
    with contextlib.suppress(HilrigError):
        replay_trace(trace, list(specs.values()), jobs=1)


def run_task(task: Task, root: Path, *, tables: bool = False) -> TaskResult:
    """Run ``task`` and write its partitions under ``root``; a HilrigError becomes the result's
    ``error`` (the sweep goes on), anything else propagates (a bug, or an interrupt)."""
    began = time.perf_counter()
    keep_freed_memory()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    layout = Layout(root)
    if layout.done(task.source, task.run, tables=tables):
        return TaskResult(task.source, task.run, worker=worker, skipped=True)
    try:
        if task.closed_loop:
            replayed = closed_replay_file(task.path, [task.spec])
        else:
            replayed = replay_trace(trace_of(task.path), [task.spec], jobs=1, arena=ARENA)
        metrics = task_metrics(task, replayed)
        layout.write(task.source, task.run, metrics, replayed.table if tables else None)
    except HilrigError as err:
        message = " ".join(str(err).split())
        code = (disk_errno(err) or 0) if isinstance(err, DiskError) else 0
        return TaskResult(task.source, task.run, worker=worker, error=message, disk_errno=code)
    seconds = time.perf_counter() - began
    subject = subject_of(metrics, task.source)
    return TaskResult(
        task.source,
        task.run,
        len(metrics),
        seconds,
        worker,
        subject=subject,
        tallies=tally(metrics),
    )


def task_metrics(task: Task, replayed: Replayed) -> pd.DataFrame:
    """The per-event metrics of the task's run (analysis's :func:`metrics_frame` rows) with
    the sweep's columns; events are found in the force this run met."""
    origin = replayed.table.attrs.get(INPUT_KEY, {})
    area = origin.get("contact_area_cm2")
    source = Source(
        task.path,
        SourceKind.REPLAY,
        runs_from_frame(replayed.table),
        subject_id=origin.get("subject_id"),
        session_id=origin.get("session_id"),
        start_ns=origin.get("t0_ns"),
        body_region=str(origin.get("body_region") or ""),
        contact_area_cm2=None if area is None else float(area),
    )
    frame = without(metrics_frame([analyze(source)]), task.excluded, source.start_ns or 0)
    settings = json.dumps({s.key: s.value for s in task.spec.settings}, sort_keys=True)
    frame = frame.assign(
        source=task.source,
        subject_id=source.subject_id,
        session_id=source.session_id,
        controller=task.spec.controller,
        settings=settings,
        input=str(task.path),
    )
    text = [*TEXT_COLUMNS, *SWEEP_COLUMNS]
    return frame.astype(dict.fromkeys(text, pd.StringDtype()))


def without(frame: pd.DataFrame, excluded: Sequence[ExcludedEvent], t0_ns: int) -> pd.DataFrame:
    """``frame``'s metrics rows (times in s since ``t0_ns``) less those of events of an
    excluded event's group whose window overlaps the excluded one's."""
    if not excluded or frame.empty:
        return frame
    out = pd.Series(False, index=frame.index)
    for event in excluded:
        start_s = (event.start_ns - t0_ns) / NS_PER_S
        end_s = (event.end_ns - t0_ns) / NS_PER_S
        overlap = (frame["start_s"] <= end_s) & (frame["end_s"] >= start_s)
        out |= (frame["group"] == event.group) & overlap
    return frame[~out]
