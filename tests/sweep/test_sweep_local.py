"""``hilrig sweep`` on the local engine: what it sweeps, what it writes, and how it resumes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pandas as pd
import pytest
from sweep_helpers import HILRIG, SWEEP, force_table, hilrig, sessions

from hilrig.analysis import Source, SourceKind, analyze, metrics_frame, runs_from_frame
from hilrig.analysis.compare import METRIC_COLUMNS
from hilrig.replay import parse_specs
from hilrig.replay.job import replay_file
from hilrig.study.study_file import StudyFile, exclude, write_study
from hilrig.sweep import METRICS, TABLES, Layout, find_inputs, partition_files, plan, read_sweep
from hilrig.sweep import sweep as run_sweep

SPECS = parse_specs(["adaptive"], sweeps=["adaptive.a1=5,10,20"])


def test_sources_are_files_folders_and_a_study_less_its_exclusions(tmp_path: Path) -> None:
    folder = sessions(tmp_path / "lab" / "day1", count=2)
    table = force_table(tmp_path / "push.parquet", 20.0)
    study = tmp_path / "study"
    kept, dropped, other = sessions(study / "sub", count=3)
    write_study(study, exclude(StudyFile(), "20260101-000002-S002", "stepped back"))
    found = find_inputs([tmp_path / "lab", table, study])
    assert [(i.source, i.path) for i in found.files] == [
        ("day1/S001.mcap", folder[0].resolve()),
        ("day1/S002.mcap", folder[1].resolve()),
        ("push.parquet", table.resolve()),
        ("sub/S001.mcap", kept.resolve()),
        ("sub/S003.mcap", other.resolve()),
    ]
    assert dropped.exists()
    assert found.notes == (
        f"study {study}: 2 sessions (2 files); left out: 1 excluded in study.toml, 0 unreadable",
    )
    tasks = plan(found, SPECS, closed_loop=False)
    assert len(tasks) == 5 * 3 and {t.run for t in tasks} == {s.name for s in SPECS}


def test_each_task_writes_what_replay_and_analyze_give_for_its_run(tmp_path: Path) -> None:
    paths = sessions(tmp_path / "in", count=2)
    out = tmp_path / "out"
    summary = run_sweep(plan(find_inputs([tmp_path / "in"]), SPECS, closed_loop=False), out)
    assert (summary.tasks, summary.already_done, len(summary.results)) == (6, 0, 6)
    assert len(partition_files(out)) == 6 and not (out / TABLES).exists()
    got = read_sweep(out)
    for path in paths:  # the same runs replayed together and analysed as one source
        together = replay_file(path, SPECS).table
        expected = metrics_frame(
            [analyze(Source(path, SourceKind.REPLAY, runs_from_frame(together)))]
        )
        mine = got[got["source"] == path.name].sort_values(["run", "event", "axis"])
        theirs = expected.sort_values(["run", "event", "axis"])
        assert len(mine) == len(theirs) > 0
        for column in METRIC_COLUMNS:
            assert mine[column].tolist() == pytest.approx(
                theirs[column].tolist(), rel=0, abs=0, nan_ok=True
            ), column
        assert set(mine["settings"]) == {'{"a1": 5.0}', '{"a1": 10.0}', '{"a1": 20.0}'}
        assert set(mine["session_id"]) == {f"20260101-00000{path.stem[-1]}-{path.stem}"}
    manifest = json.loads((out / "sweep.json").read_text())
    assert manifest["loop"] == "open" and set(manifest["runs"]) == {s.name for s in SPECS}


def test_tables_and_a_source_without_collisions(tmp_path: Path) -> None:
    quiet = tmp_path / "quiet.parquet"
    pd.DataFrame(
        {"t": [i / 1000 for i in range(3000)], "fx": 0.0, "fy": 0.0, "fz": 0.0}
    ).to_parquet(quiet)
    out = tmp_path / "out"
    tasks = plan(
        find_inputs([quiet, force_table(tmp_path / "f.parquet", 15.0)]),
        SPECS[:2],
        closed_loop=False,
    )
    run_sweep(tasks, out, tables=True, workers=2)
    assert len(partition_files(out, METRICS)) == len(partition_files(out, TABLES)) == 4
    metrics = read_sweep(out)
    assert set(metrics["source"]) == {"f.parquet"}  # the quiet one has no event rows
    table = read_sweep(out, TABLES)
    assert len(table) == 2 * (3000 + 15000) and set(table["run"]) == {s.name for s in SPECS[:2]}


def test_a_rerun_skips_what_is_done_and_ignores_an_unfinished_file(tmp_path: Path) -> None:
    sessions(tmp_path / "in", count=2)
    out = tmp_path / "out"
    tasks = plan(find_inputs([tmp_path / "in"]), SPECS, closed_loop=False)
    run_sweep(tasks[:4], out)  # an interrupted sweep: 4 of 6 tasks written
    before = {p: p.stat().st_mtime_ns for p in partition_files(out)}
    assert len(before) == 4
    missing = Layout(out).partition(METRICS, tasks[5].source, tasks[5].run)
    missing.parent.mkdir(parents=True)
    leftover = missing.with_name(".part-0.0badf00d.partial.parquet")
    leftover.write_bytes(b"PAR1 cut short by a killed worker")
    assert not Layout(out).done(tasks[5].source, tasks[5].run, tables=False)
    summary = run_sweep(tasks, out)
    assert (summary.already_done, len(summary.results), summary.temporaries_removed) == (4, 2, 1)
    after = {p: p.stat().st_mtime_ns for p in partition_files(out)}
    assert len(after) == 6 and {p: after[p] for p in before} == before
    assert not leftover.exists() and len(read_sweep(out)) == len(read_sweep(out).drop_duplicates())
    again = run_sweep(tasks, out)
    assert (again.already_done, len(again.results)) == (6, 0)


def test_an_interrupted_command_completes_when_run_again(tmp_path: Path) -> None:
    (tmp_path / "in").mkdir()
    inputs = [str(force_table(tmp_path / "in" / f"t{n}.parquet", 300.0, seed=n)) for n in range(3)]
    out = tmp_path / "out"
    command = ["sweep", *inputs, *SWEEP, "--out", str(out), "--workers", "1"]
    process = subprocess.Popen(
        [str(HILRIG), *command], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 60
        while not partition_files(out) and time.monotonic() < deadline:
            time.sleep(0.02)
        process.send_signal(signal.SIGINT)  # Ctrl-C: the running task ends, the rest dropped
        _, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert stderr.strip().endswith("interrupted: stopped by Ctrl-C")
    before = {p: p.stat().st_mtime_ns for p in partition_files(out)}
    assert 1 <= len(before) < 9
    result = hilrig(*command)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(
        f"9 tasks (3 sources x 3 parameter sets): {len(before)} already done, {9 - len(before)} run"
    )
    after = {p: p.stat().st_mtime_ns for p in partition_files(out)}
    assert len(after) == 9 and {p: after[p] for p in before} == before
    assert not list(out.rglob(".*partial*"))


def test_a_folder_of_another_sweep_or_other_files_is_refused(tmp_path: Path) -> None:
    table = force_table(tmp_path / "f.parquet", 5.0)
    out = tmp_path / "out"
    result = hilrig(
        "sweep", str(table), "-c", "soft=adaptive", "--set", "soft.a1=5", "-o", str(out)
    )
    assert result.returncode == 0, result.stderr
    other = hilrig("sweep", str(table), "-c", "soft=adaptive", "--set", "soft.a1=9", "-o", str(out))
    assert other.returncode == 2
    assert other.stderr == (
        f"error: --out {out}: run 'soft' was swept there with other settings ({{\"controller\": "
        '"soft", "law": "adaptive", "settings": ["a1=5"]}); name it differently or choose another '
        "folder\n"
    )
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    busy = hilrig("sweep", str(table), "-o", str(tmp_path / "busy"))
    assert busy.stderr == (
        f"error: --out {tmp_path / 'busy'}: not empty and holds no sweep.json; choose another "
        "folder\n"
    )
    assert os.listdir(tmp_path / "busy") == ["notes.txt"]


def test_closed_loop_on_a_recording_of_the_live_loop(tmp_path: Path) -> None:
    example = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
    specs = parse_specs(["fixed", "adaptive"])
    summary = run_sweep(
        plan(find_inputs([example], closed_loop=True), specs, closed_loop=True), tmp_path
    )
    assert len(summary.results) == 2 and not [r for r in summary.results if r.error]
    metrics = read_sweep(tmp_path)
    assert set(metrics["run"]) == {"fixed", "adaptive"}
    assert json.loads((tmp_path / "sweep.json").read_text())["loop"] == "closed"
    assert set(metrics["law"]) == {"fixed", "adaptive"}
    assert (metrics.groupby("run")["peak_force"].max() > 1.0).all()  # N: the collision
