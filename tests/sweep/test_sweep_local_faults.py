"""The local engine when its workers die: real worker processes killed with SIGKILL mid-sweep
(the kernel's out-of-memory killer sends the same); the sweep replaces the broken pool and
completes, or stops in one line after ``MAX_RETRIES`` replacements."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pandas as pd
import pytest
from sweep_helpers import force_table

from hilrig.replay import parse_specs
from hilrig.sweep import (
    SweepError,
    SweepWarning,
    TaskResult,
    find_inputs,
    partition_files,
    plan,
    read_sweep,
    sweep,
)
from hilrig.sweep.engines import MAX_RETRIES

SPECS = parse_specs(["adaptive"], sweeps=["adaptive.a1=5,10,20"])


def kill_its_worker(result: TaskResult) -> None:
    """SIGKILL the pool worker that delivered ``result`` (its ``worker`` is host:pid)."""
    os.kill(int(result.worker.rpartition(":")[2]), signal.SIGKILL)


def test_a_worker_killed_mid_sweep_loses_no_result(tmp_path: Path) -> None:
    inputs = [force_table(tmp_path / f"t{n}.parquet", 300.0, seed=n) for n in range(3)]
    tasks = plan(find_inputs(inputs), SPECS, closed_loop=False)
    reference = sweep(tasks, tmp_path / "reference", workers=1)
    assert not reference.results[0].error
    seen: list[TaskResult] = []

    def on_result(result: TaskResult) -> None:
        seen.append(result)
        if len(seen) == 1:
            kill_its_worker(result)  # the pool breaks; the other worker is mid-task

    with pytest.warns(SweepWarning) as caught:
        summary = sweep(tasks, tmp_path / "out", workers=2, on_result=on_result)
    (warning,) = [str(w.message) for w in caught]
    lost = int(warning.split(": ")[1].split()[0])
    assert 1 <= lost <= len(tasks) - 1
    assert warning == (
        f"a worker process died (killed, or out of memory): {lost} unfinished tasks run again "
        f"on a new pool (retry 1 of {MAX_RETRIES})"
    )
    assert sorted((r.source, r.run) for r in summary.results) == sorted(
        (t.source, t.run) for t in tasks
    )
    assert not [r for r in summary.results if r.error]
    assert len(partition_files(tmp_path / "out")) == len(tasks) == 9
    pd.testing.assert_frame_equal(read_sweep(tmp_path / "out"), read_sweep(tmp_path / "reference"))


def test_a_pool_broken_again_and_again_stops_in_one_line(tmp_path: Path) -> None:
    inputs = [force_table(tmp_path / f"t{n}.parquet", 120.0, seed=n) for n in range(8)]
    tasks = plan(find_inputs(inputs), SPECS, closed_loop=False)
    with pytest.warns(SweepWarning) as caught, pytest.raises(SweepError) as raised:
        sweep(tasks, tmp_path / "out", workers=2, on_result=kill_its_worker)
    assert str(raised.value) == (
        f"worker processes died {MAX_RETRIES + 1} times (killed, or out of memory); the finished "
        "tasks are kept: run the same command again to complete the sweep"
    )
    assert [str(w.message).rpartition("(")[2] for w in caught] == [
        f"retry {n} of {MAX_RETRIES})" for n in range(1, MAX_RETRIES + 1)
    ]
    kept = len(partition_files(tmp_path / "out"))
    assert 1 <= kept < len(tasks)
    again = sweep(tasks, tmp_path / "out", workers=2)  # a rerun completes it
    assert again.already_done >= kept and len(partition_files(tmp_path / "out")) == len(tasks)
