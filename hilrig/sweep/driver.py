"""A sweep from start to end: the output checked, done tasks skipped, the rest run on an engine.

    inputs = find_inputs([Path("study")])
    specs = parse_specs(["adaptive"], sweeps=["adaptive.a1=5:20:4"])
    tasks = plan(inputs, specs, closed_loop=False)
    summary = sweep(tasks, Path("out"), engine="ray", address="10.0.0.5:6379")
    metrics = read_sweep(Path("out"))

Rerunning a sweep into the same folder runs only the tasks whose partitions are not all in
place (an interrupted sweep completes; one that completed does nothing). Tasks that fail with
an explained error (a HilrigError: an input that cannot be replayed) do not stop the others;
the sweep then raises SweepError naming the first, and a rerun retries only the failed ones.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from hilrig.errors import DiskError, SweepError
from hilrig.outputs import DISK_ERRORS
from hilrig.sweep.dataset import MANIFEST, METRICS, Layout, describe_runs, prepare
from hilrig.sweep.engines import ENGINES, local_results, ray_results
from hilrig.sweep.summary import Tally, read_tally
from hilrig.sweep.tasks import Task, TaskResult

#: ``progress(done, total)``: tasks finished (the ones done before this run included), of all.
Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class SweepSummary:
    """What a sweep did: tasks in all, found done, run here (with their results), where, and
    its summary: each run's collisions across subjects (:mod:`.summary`, every task's)."""

    root: Path
    tasks: int
    already_done: int
    results: tuple[TaskResult, ...]
    seconds: float
    engine: str
    by_run: pd.DataFrame  # .summary.SUMMARY_COLUMNS
    by_subject: pd.DataFrame  # .summary.SUBJECT_COLUMNS: the subjects' values behind by_run
    temporaries_removed: int = 0

    @property
    def nodes(self) -> frozenset[str]:
        """The Ray nodes that ran tasks (empty for the local engine)."""
        return frozenset(r.node for r in self.results if r.node)

    @property
    def workers(self) -> frozenset[str]:
        return frozenset(r.worker for r in self.results if r.worker)

    @property
    def rows(self) -> int:
        return sum(r.rows for r in self.results)


def sweep(
    tasks: Sequence[Task],
    root: Path,
    *,
    tables: bool = False,
    engine: str = "local",
    address: str | None = None,
    workers: int | None = None,
    progress: Progress | None = None,
    on_result: Callable[[TaskResult], None] | None = None,
) -> SweepSummary:
    """Run every task not yet done into ``root`` on ``engine`` (``local``: ``workers``
    processes, default one per core; ``ray``: the cluster at ``address``, else RAY_ADDRESS, else
    a local instance of ``workers`` CPUs). ``on_result`` sees each result as it comes. Raises
    SweepError for a folder that holds another sweep, an engine that cannot start, or tasks
    that failed (after running all the others); DiskError at the first task whose results a
    disk refused (no other task starts; what this sweep made and left empty is removed)."""
    from hilrig.replay.engine import local_cores

    if engine not in ENGINES:
        raise SweepError(f"--engine {engine}: unknown; known: {', '.join(ENGINES)}")
    began = time.perf_counter()
    specs = {task.spec.name: task.spec for task in tasks}
    excluded = {t.source: [[e.group, e.start_ns, e.end_ns] for e in t.excluded] for t in tasks}
    closed = any(t.closed_loop for t in tasks)
    made_root, made_manifest = not root.exists(), not (root / MANIFEST).exists()
    prepare(root, describe_runs(specs.values()), closed_loop=closed, excluded=excluded)
    layout = Layout(root)
    todo = [t for t in tasks if not layout.done(t.source, t.run, tables=tables)]
    finished = len(tasks) - len(todo)
    runs_tally = Tally(list(specs))
    if progress is not None:
        progress(finished, len(tasks))
    count = workers or local_cores()
    results: Iterator[TaskResult]
    if not todo:
        results = iter(())
    elif engine == "local":
        results = local_results(todo, root, tables=tables, workers=min(count, len(todo)))
    else:
        results = ray_results(todo, root, tables=tables, address=address, workers=workers)
    collected: list[TaskResult] = []
    for result in results:
        collected.append(result)
        if result.disk_errno:  # every other task would meet the same disk
            _stop(results)
            break
        finished += 1
        if result.skipped:
            _add_written(runs_tally, layout, result.source, result.run)
        elif not result.error:
            runs_tally.add(result.run, result.source, result.subject, result.tallies)
        if on_result is not None:
            on_result(result)
        if progress is not None:
            progress(finished, len(tasks))
    refused = next((r for r in collected if r.disk_errno), None)
    if refused is not None:
        layout.remove_temporaries()
        layout.remove_empty(manifest=made_manifest, root=made_root)
        raise DiskError(_disk_message(refused, collected, len(todo), root))
    failed = [r for r in collected if r.error]
    owed = {(t.source, t.run) for t in todo}
    for task in tasks:  # after the new work, so that a damaged old partition delays none of it
        if (task.source, task.run) not in owed:
            _add_written(runs_tally, layout, task.source, task.run)
    removed = 0 if failed else layout.remove_temporaries()
    seconds = time.perf_counter() - began
    done_before = len(tasks) - len(todo)
    summary = SweepSummary(
        root,
        len(tasks),
        done_before,
        tuple(collected),
        seconds,
        engine,
        runs_tally.table(),
        runs_tally.by_subject(),
        removed,
    )
    if failed:
        first = failed[0]
        raise SweepError(
            f"{len(failed)} of {len(todo)} tasks failed (the others are written in {root}; run "
            f"the same command again to retry the failed ones); first: source {first.source}, "
            f"run {first.run}: {first.error}"
        )
    return summary


def _add_written(by_run: Tally, layout: Layout, source: str, run: str) -> None:
    """Add to ``by_run`` the metrics a task wrote before (its result carries no tallies)."""
    by_run.add(run, source, *read_tally(layout.partition(METRICS, source, run), source))


def _stop(results: Iterator[TaskResult]) -> None:
    """End an engine's results: its pool drops the tasks not started (running ones finish)."""
    if isinstance(results, Generator):
        results.close()


def _disk_message(refused: TaskResult, results: Sequence[TaskResult], todo: int, root: Path) -> str:
    """One line for a sweep whose disk refused ``refused``'s results: what, where, what of
    this run is kept (whole tasks, which a rerun skips), what to do."""
    meaning, remedy = DISK_ERRORS[refused.disk_errno]
    written = sum(1 for r in results if not r.error and not r.skipped)
    what = f"could not write the results of source {refused.source}, run {refused.run} ({root})"
    if not written:
        return f"{meaning}: {what}: nothing was written; {remedy}"
    return (
        f"{meaning}: {what}: {written} of {todo} tasks were written whole before it; "
        f"{remedy.removesuffix(' and run again')} and run the same command again for the rest"
    )
