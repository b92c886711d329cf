"""Where a sweep's tasks run: a local process pool, or Ray (one machine or a cluster).

Both run the same function (:func:`hilrig.sweep.tasks.run_task`) and yield its results as
tasks finish, in any order. Scheduling, retries and placement are the engine's own:

- ``local``: a ``ProcessPoolExecutor`` of forked workers (this process's imports inherited).
  A worker that dies breaks the pool: the unfinished tasks run again on a new pool, up to
  ``MAX_RETRIES`` broken pools (then the sweep stops with one line, and a rerun completes it).
  Ctrl-C ends the running tasks at once (a task's files are written under hidden temporary
  names and renamed when whole, so nothing cut short is ever read; a rerun redoes them).
- ``ray``: each task a Ray remote task (one CPU), retried by Ray up to ``MAX_RETRIES`` times
  when its worker or node dies; at most ``IN_FLIGHT_PER_CPU`` tasks per cluster CPU are
  submitted at once (``ray.wait`` frees a slot), so a huge sweep never floods the scheduler.
  Ray is imported here only, when this engine runs (an optional extra: ``hilrig[ray]``).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import warnings
from collections.abc import Generator, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

from hilrig.errors import SweepError
from hilrig.libc import linux_libc
from hilrig.ray_address import INSTALL_HINT, check_reachable, cluster_address
from hilrig.sweep.tasks import Task, TaskResult, run_task, warm_up

ENGINES = ("local", "ray")
#: Ray retries a task whose worker or node died this many times, and the local engine replaces
#: a pool broken by a dead worker this many times (a task's partitions are rewritten whole,
#: never appended to; one found done is not run again).
MAX_RETRIES = 3
#: Tasks submitted to Ray at once, per CPU of the cluster.
IN_FLIGHT_PER_CPU = 2
#: Ray's own C++ log lines on the terminal: errors only (its warnings are retries hilrig
#: reports itself), unless RAY_BACKEND_LOG_LEVEL says otherwise.
RAY_LOG_LEVEL = "error"
PR_SET_PDEATHSIG = 1  # Linux prctl: the signal a process gets when its parent ends


class SweepWarning(UserWarning):
    """A sweep recovered from a fault (a local worker died; its unfinished tasks run again)."""


def local_results(
    tasks: Sequence[Task], root: Path, *, tables: bool, workers: int
) -> Iterator[TaskResult]:
    """Each task's result from a pool of ``workers`` processes, as they finish. When a worker
    dies (killed, out of memory) the pool breaks: the tasks it had not finished run again on a
    new pool (with a warning), up to ``MAX_RETRIES`` times; then SweepError. The workers are
    forked, where the OS can, after :func:`.warm_up` (kernels loaded once, here)."""
    if _start_method() == "fork":
        warm_up(tasks)
    left = list(tasks)
    for attempt in range(MAX_RETRIES + 1):
        if attempt:
            warnings.warn(
                f"a worker process died (killed, or out of memory): {len(left)} unfinished "
                f"tasks run again on a new pool (retry {attempt} of {MAX_RETRIES})",
                SweepWarning,
                stacklevel=2,
            )
        left = yield from _pool_results(left, root, tables=tables, workers=workers)
        if not left:
            return
    raise SweepError(
        f"worker processes died {MAX_RETRIES + 1} times (killed, or out of memory); the "
        "finished tasks are kept: run the same command again to complete the sweep"
    )


def _pool_results(
    tasks: Sequence[Task], root: Path, *, tables: bool, workers: int
) -> Generator[TaskResult, None, list[Task]]:
    """Each task's result from one pool, as they finish; returns the tasks it lost to a
    broken pool (a worker that died), in their order."""
    sys.stdout.flush()
    sys.stderr.flush()
    context = multiprocessing.get_context(_start_method())
    size = max(1, min(workers, len(tasks)))
    pool = ProcessPoolExecutor(size, mp_context=context, initializer=_worker_init)
    lost: list[int] = []
    try:
        pending: dict[Future[TaskResult], int] = {}
        for index, task in enumerate(tasks):
            try:
                pending[pool.submit(run_task, task, root, tables=tables)] = index
            except BrokenProcessPool:
                lost.extend(range(index, len(tasks)))
                break
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                index = pending.pop(future)
                try:
                    result = future.result()
                except BrokenProcessPool:
                    lost.append(index)
                else:
                    yield result
    except KeyboardInterrupt:  # Ctrl-C: the running tasks end too, their files unfinished
        for worker in list(pool._processes.values()):
            worker.terminate()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return [tasks[index] for index in sorted(lost)]


def _start_method() -> str:
    """How pool workers start: forked where the OS can, else spawned."""
    return "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"


def _worker_init() -> None:
    """A pool worker: Ctrl-C is the sweep's to handle (it ends the workers and drops every
    task), and on Linux the worker ends with the sweep's process, however that ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    libc = linux_libc()
    if libc is not None:
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


def import_ray() -> ModuleType:
    """The ``ray`` module; SweepError (one line, how to install it) when it is not installed."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage reports unless asked
    os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", RAY_LOG_LEVEL)
    try:
        import ray
    except ImportError:
        message = f"--engine ray needs Ray, which is not installed: {INSTALL_HINT}"
        raise SweepError(message) from None
    return ray


def ray_results(
    tasks: Sequence[Task],
    root: Path,
    *,
    tables: bool,
    address: str | None = None,
    workers: int | None = None,
) -> Iterator[TaskResult]:
    """Each task's result from Ray remote tasks, as they finish. Joins the cluster at
    ``address`` (else ``RAY_ADDRESS``), else starts a local instance of ``workers`` CPUs; one
    this call connected or started is shut down at the end."""
    ray = import_ray()
    target = cluster_address(address)
    check_reachable(target)
    started = not ray.is_initialized()
    if started:
        options: dict[str, Any] = {"logging_level": "WARNING", "log_to_driver": False}
        if target is None:
            options |= {"num_cpus": workers, "include_dashboard": False}
        try:
            ray.init(address=target, **options)
        except (ConnectionError, RuntimeError, ValueError) as err:
            message = " ".join(str(err).split())
            raise SweepError(f"cannot join the Ray cluster at {target}: {message}") from None
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(ray_task)
    limit = max(2, IN_FLIGHT_PER_CPU * int(ray.cluster_resources().get("CPU", 1)))
    queue = iter(tasks)
    pending: dict[Any, Task] = {}
    try:
        while True:
            for task in queue:
                pending[remote.remote(task, root, tables)] = task
                if len(pending) >= limit:
                    break
            if not pending:
                return
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                task = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayError as err:  # retries exhausted, or cancelled
                    message = " ".join(str(err).split())[:300]
                    yield TaskResult(task.source, task.run, error=f"Ray: {message}")
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def ray_task(task: Task, root: Path, tables: bool) -> TaskResult:
    """:func:`run_task` in a Ray worker; its result names the node it ran on."""
    import ray

    result = run_task(task, root, tables=tables)
    return replace(result, node=ray.get_runtime_context().get_node_id())
