"""Damaged recordings through every reader (hypothesis, derandomized): byte flips, insertions of
random bytes and cuts, several per file, in the header, the metadata, the first chunk, the
summary, the footer and anywhere.

Each call either gives correct data for what is intact (frames equal to the undamaged file's
rows; messages ``recover`` keeps byte-identical to the original's through the official reader)
and says the file is damaged whenever it is, or fails with one ``error:`` line (exit 2); never a
traceback, never a hang, never an output left behind by a failure. 1000 files go through the
library (info with and without the full check, load, recover), 250 through the command line's
info, recover and export, 100 through replay and analyze.
"""

from __future__ import annotations

import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fuzz_helpers import (
    Base,
    bounded,
    changes,
    damaged,
    hilrig,
    official_messages,
    values,
    write_base,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hilrig.errors import HilrigError, OutputError, RecordingError
from hilrig.recording import RecordingWarning, inspect, load, recover

pytestmark = pytest.mark.filterwarnings("ignore::hilrig.recording.RecordingWarning")
FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Base:
    return write_base(tmp_path_factory.mktemp("fuzz"))


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-work")


def one_line(err: HilrigError, path: Path) -> None:
    assert "\n" not in str(err) and str(path) in str(err), str(err)


def same_rows(frames: dict[str, pd.DataFrame], base: Base, *, whole: bool) -> None:
    """Every loaded row is the undamaged file's row at that log time, value for value and of
    the same dtypes; all of them if ``whole``. (What pandas' assert_frame_equal with
    check_categorical=False checks, vectorised: it boxes every categorical cell, most of this
    test's time.)"""
    if whole:
        assert set(frames) == set(base.frames)
    for topic, frame in frames.items():
        original = base.frames[topic]
        if frame.empty and not whole:
            continue  # a topic whose messages were all lost has no columns to compare
        at = original.index.get_indexer(frame.index)
        assert frame.index.is_unique and (at >= 0).all(), topic
        assert frame.index.dtype == original.index.dtype, topic
        assert list(frame.columns) == list(original.columns), topic
        for name, column in frame.items():
            expected = original[name]
            assert (column.dtype == expected.dtype) or (
                isinstance(column.dtype, pd.CategoricalDtype)
                and isinstance(expected.dtype, pd.CategoricalDtype)
            ), (topic, name, column.dtype, expected.dtype)
            loaded, kept = values(column), base.columns[topic][name][at]
            floats = loaded.dtype.kind == "f"
            assert np.array_equal(loaded, kept, equal_nan=floats), (topic, name)
        assert not whole or len(frame) == len(original), topic


def check_info(path: Path, base: Base, *, damaged_file: bool) -> None:
    try:
        with bounded(10):
            quick = inspect(path)
    except RecordingError as err:
        one_line(err, path)
        with pytest.raises(RecordingError):
            inspect(path, check=True)
        return
    assert bool(quick.problems) == damaged_file, quick.problems  # the data CRC is checked
    if not quick.problems:
        assert quick.complete and quick.verified
        assert {t.topic: t.count for t in quick.topics} == base.counts
    with bounded(10):
        full = inspect(path, check=True)
    assert bool(full.problems) == damaged_file, full.problems
    assert full.complete == (not damaged_file)
    for line in full.problems:
        assert "\n" not in line and line.startswith(f"{path}: "), line


def check_load(path: Path, base: Base) -> None:
    with warnings.catch_warnings(record=True) as caught, bounded(10):
        warnings.simplefilter("always")
        try:
            frames = load(path)
        except RecordingError as err:
            one_line(err, path)
            return
    problems = [w for w in caught if issubclass(w.category, RecordingWarning)]
    assert len(problems) == len(caught), [str(w.message) for w in caught]
    same_rows(frames, base, whole=not problems)


def check_recover(path: Path, base: Base, out: Path, *, damaged_file: bool) -> None:
    try:
        with bounded(10):
            recovery = recover(path, out)
    except RecordingError as err:
        one_line(err, path)
        assert not out.exists() and not list(out.parent.iterdir())
        return
    assert list(out.parent.iterdir()) == [out]
    kept = official_messages(out)
    assert sum(kept.values()) == recovery.messages
    assert not kept - base.messages, "a kept message differs from every original one"
    assert recovery.was_complete == (not damaged_file) == (not recovery.problems)
    if recovery.was_complete:
        assert kept == base.messages
    if recovery.lost:
        assert recovery.messages + sum(recovery.lost.values()) == sum(base.messages.values())
    out.unlink()


@settings(FUZZ, max_examples=1000)
@given(data=st.data())
def test_damaged_files_through_the_library(base: Base, work: Path, data: st.DataObject) -> None:
    damaged_bytes = damaged(base.data, data.draw(changes(base)))
    folder = Path(tempfile.mkdtemp(dir=work))
    try:
        path = folder / "damaged.mcap"
        path.write_bytes(damaged_bytes)
        is_damaged = damaged_bytes != base.data
        check_info(path, base, damaged_file=is_damaged)
        check_load(path, base)
        out = folder / "out" / "recovered.mcap"
        out.parent.mkdir()
        check_recover(path, base, out, damaged_file=is_damaged)
    finally:
        shutil.rmtree(folder)


@settings(FUZZ, max_examples=250)
@given(data=st.data())
def test_damaged_files_through_the_command_line(
    base: Base, work: Path, data: st.DataObject
) -> None:
    damaged_bytes = damaged(base.data, data.draw(changes(base)))
    folder = Path(tempfile.mkdtemp(dir=work))
    try:
        path = folder / "damaged.mcap"
        path.write_bytes(damaged_bytes)
        whole = 1 if damaged_bytes != base.data else 0
        quick = hilrig("info", str(path))
        full = hilrig("info", "--check", str(path))
        assert quick.exit_code == full.exit_code == (2 if quick.exit_code == 2 else whole)
        out = folder / "recovered"
        out.mkdir()
        recovered = hilrig("recover", str(path), "-o", str(out / "r.mcap"))
        assert recovered.exit_code == (2 if quick.exit_code == 2 else whole)
        left = sorted(p.name for p in out.iterdir())
        assert left == ([] if recovered.exit_code == 2 else ["r.mcap"])
        tables = folder / "tables"
        exported = hilrig("export", str(path), "--out", str(tables))
        lines = exported.stdout.splitlines()
        written = [line.removeprefix("wrote ") for line in lines if line.startswith("wrote ")]
        if exported.exit_code == 2:
            assert not tables.exists()
        else:
            assert sorted(str(p) for p in tables.iterdir()) == sorted(written)
            assert written and all(w.endswith((".parquet", ".json")) for w in written)
    finally:
        shutil.rmtree(folder)


@settings(FUZZ, max_examples=100)
@given(data=st.data())
def test_damaged_files_through_replay_and_analyze(
    base: Base, work: Path, data: st.DataObject
) -> None:
    damaged_bytes = damaged(base.data, data.draw(changes(base)))
    folder = Path(tempfile.mkdtemp(dir=work))
    try:
        path = folder / "damaged.mcap"
        path.write_bytes(damaged_bytes)
        out = folder / "replayed"
        out.mkdir()
        result = out / "r.parquet"
        replayed = hilrig("replay", str(path), "-c", "fixed", "-o", str(result), "-j", "1")
        left = sorted(p.name for p in out.iterdir())
        assert left == ([] if replayed.exit_code == 2 else ["r.parquet"]), replayed
        hilrig("analyze", str(path))
    finally:
        shutil.rmtree(folder)


def test_the_base_file_passes_every_check(base: Base, work: Path) -> None:
    """The undamaged file: whole everywhere (the fuzz tests' oracle rests on it)."""
    check_info(base.path, base, damaged_file=False)
    check_load(base.path, base)
    out = work / "base-out" / "recovered.mcap"
    out.parent.mkdir()
    check_recover(base.path, base, out, damaged_file=False)
    assert hilrig("info", "--check", str(base.path)).exit_code == 0
    with pytest.raises(OutputError):
        recover(base.path, base.path)
