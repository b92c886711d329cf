"""A sweep worker's memory: what one task frees, the next one reuses.

A task replays a session (ten minutes at 1 kHz through one controller: a result table of about
260 MB) and analyses the result. Left alone, each task would take all of that as fresh memory:
the replay maps its table anew, and glibc's ``malloc`` hands large blocks back to the system
when they are freed. Fresh memory is zeroed by the kernel page by page: measured here, about
70,000 page faults per task and as much system time as the task's own work, which two workers
then pay side by side (docs/sweeps.md). So, once per worker process:

- replays take their tables from :data:`ARENA`, one mapping kept for the process
  (:class:`hilrig.replay.blocks.Arena`);
- ``malloc`` serves large blocks from its heap and keeps what is freed (``mallopt``: no
  ``mmap`` for large blocks, no trimming of the heap's top), on glibc; elsewhere nothing changes.

The price: a worker holds as much memory as its largest task needed, until the sweep ends.

A sweep's tasks come by input then parameter set, so a worker's next task is mostly another
parameter set of the same session: :func:`trace_of` keeps the last force trace a worker loaded
and gives it again while the file is unchanged (loading a 10-minute table was about 30 % of a
task's time). The trace is only read by a replay (:func:`hilrig.replay.job.replay_trace`).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from hilrig.libc import linux_libc
from hilrig.replay import ForceTrace, load_trace
from hilrig.replay.blocks import Arena

#: glibc's mallopt parameters (malloc.h).
M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_MAX = -1, -2, -4
#: The heap's freed top is kept up to this many bytes (C int: the largest allowed).
TRIM_THRESHOLD_BYTES = 2**31 - 1
#: The heap grows by this much more than asked, in one step.
TOP_PAD_BYTES = 1 << 26

#: This process's replay memory, reused from one task to the next (a task's result table never
#: outlives the task).
ARENA = Arena()


@functools.cache
def keep_freed_memory() -> None:
    """Have ``malloc`` keep what this process frees for its next allocations (once per
    process; on Linux with glibc, nothing elsewhere)."""
    mallopt = getattr(linux_libc(), "mallopt", None)
    if mallopt is None:  # not Linux, or not glibc
        return
    mallopt(M_MMAP_MAX, 0)
    mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
    mallopt(M_TOP_PAD, TOP_PAD_BYTES)


#: The last trace :func:`trace_of` loaded in this process, under its file's identity.
_last: dict[tuple[str, int, int, int, int], ForceTrace] = {}


def trace_of(path: Path) -> ForceTrace:
    """The force trace in ``path`` (:func:`hilrig.replay.load_trace`), the one loaded last
    again when ``path`` is the same path to the same file, unchanged (device, inode, size and
    modification time; the path as given, since the trace names its source by it); raises
    what ``load_trace`` raises."""
    try:
        where = os.stat(path)
    except OSError:
        return load_trace(path)  # which says what is wrong, in one line
    key = (str(path), where.st_dev, where.st_ino, where.st_size, where.st_mtime_ns)
    trace = _last.get(key)
    if trace is None:
        _last.clear()  # the old trace is freed before the new one is loaded
        trace = _last[key] = load_trace(path)
    return trace
