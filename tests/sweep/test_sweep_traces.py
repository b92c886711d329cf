"""A sweep worker's last force trace, given again to the next task of the same unchanged file
(``hilrig.sweep.memory.trace_of``), and never changed by the tasks that replay it."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from sweep_helpers import force_table

from hilrig.replay import load_trace, parse_specs
from hilrig.sweep import find_inputs, plan
from hilrig.sweep.memory import trace_of
from hilrig.sweep.tasks import run_task


def test_the_same_unchanged_file_gives_the_same_trace_and_a_changed_one_is_read_again(
    tmp_path: Path,
) -> None:
    first = force_table(tmp_path / "a.parquet", 3.0, seed=1)
    other = force_table(tmp_path / "b.parquet", 3.0, seed=2)
    trace = trace_of(first)
    assert trace_of(first) is trace
    assert trace_of(other) is not trace  # only the last one is kept
    again = trace_of(first)
    assert again is not trace and np.array_equal(again.force, trace.force)
    force_table(first, 4.0, seed=3)  # the file rewritten in place
    os.utime(first, ns=(1, 1))  # whatever its time: its size differs
    changed = trace_of(first)
    assert changed is not again and changed.ticks == 4000
    assert np.array_equal(changed.force, load_trace(first).force)


def test_tasks_replaying_the_kept_trace_leave_it_as_it_was_read(tmp_path: Path) -> None:
    path = force_table(tmp_path / "trace.parquet", 25.0)
    specs = parse_specs(["adaptive", "fixed"], sweeps=["adaptive.a1=5,20"])
    tasks = plan(find_inputs([path]), specs, closed_loop=False)
    kept = trace_of(path)
    before = kept.force.copy()
    for task in tasks:
        result = run_task(task, tmp_path / "out")
        assert not result.error and result.rows > 0
    assert trace_of(path) is kept
    assert np.array_equal(kept.force, before) and np.array_equal(before, load_trace(path).force)
