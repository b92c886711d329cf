"""Parameter sweeps: every session of a study through a grid of controller parameters, with the
per-event metrics of each (session, parameter set) as one partition of a Parquet dataset, on a
local process pool or a Ray cluster (``hilrig sweep``; docs/sweeps.md)::

    inputs = find_inputs([Path("study")])                      # files, folders, study folders
    tasks = plan(inputs, parse_specs(sweeps=["adaptive.a1=5:20:4"]), closed_loop=False)
    summary = sweep(tasks, Path("out"), engine="local")        # or "ray", address=...
    metrics = read_sweep(Path("out"))                          # one row per run, event, axis
    summary.by_run, summarise(Path("out"))                     # per run: across subjects
    summary.by_subject                                         # the subjects' values behind it
    report.write_sweep_report(summary, specs, Path("r.html"))  # hilrig.sweep.report (matplotlib)

A rerun into the same folder skips what is done, so an interrupted sweep completes.
"""

from hilrig.errors import SweepError
from hilrig.sweep.dataset import METRICS, TABLES, Layout, partition_files, read_sweep
from hilrig.sweep.driver import SweepSummary, sweep
from hilrig.sweep.engines import ENGINES, SweepWarning
from hilrig.sweep.inputs import ExcludedEvent, Input, Inputs, find_inputs
from hilrig.sweep.summary import SUBJECT_COLUMNS, SUMMARY_COLUMNS, summarise
from hilrig.sweep.tasks import Task, TaskResult, plan, run_task

__all__ = [
    "ENGINES",
    "METRICS",
    "SUBJECT_COLUMNS",
    "SUMMARY_COLUMNS",
    "TABLES",
    "ExcludedEvent",
    "Input",
    "Inputs",
    "Layout",
    "SweepError",
    "SweepSummary",
    "SweepWarning",
    "Task",
    "TaskResult",
    "find_inputs",
    "partition_files",
    "plan",
    "read_sweep",
    "run_task",
    "summarise",
    "sweep",
]
