"""Damaged recordings through the command line (hypothesis, derandomized): 250 files through
``info``, ``recover`` and ``export``, 100 through ``replay`` and ``analyze``; the damage is that of
``test_fuzz_damaged_files.py`` (which puts 2000 through the library). Each call exits 0, 1
(damaged) or 2 with one ``error:`` line, and a failure leaves no output behind."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from fuzz_helpers import FUZZ, Base, changes, damaged, hilrig
from hypothesis import given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.filterwarnings("ignore::hilrig.recording.RecordingWarning")


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
