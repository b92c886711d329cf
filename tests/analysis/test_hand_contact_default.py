"""``hilrig record --scenario hand-contact`` with every other default (the circle task): the hand
meets the tool wherever the task has moved it, and ``hilrig analyze`` finds that one collision
and judges it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from hilrig.analysis import read_dataset

HILRIG = Path(sys.executable).with_name("hilrig")
SECONDS = 6.0  # the default hand: from 2 s, 0.8 s in, 1 s held, 0.8 s out; next at 12 s


def test_a_default_hand_contact_session_has_one_collision_with_a_verdict(tmp_path: Path) -> None:
    out, dataset = tmp_path / "hand.mcap", tmp_path / "dataset"
    record = [str(HILRIG), "record", "--subject", "S004", "--scenario", "hand-contact"]
    record += ["--duration", str(SECONDS), "--out", str(out)]
    # the timeout includes the wait for the machine's other sessions (make test beside another)
    done = subprocess.run(record, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    analyze = [str(HILRIG), "analyze", str(out), "--out", str(dataset)]
    done = subprocess.run(analyze, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    rows = read_dataset(dataset)
    collisions = rows[rows["group"] == "cartesian"]
    assert collisions["event"].nunique() == 1
    row = collisions[collisions["axis"] == "y"].iloc[0]  # the hand pushes along base y
    assert row["peak_force_n"] > 1.0
    assert row["body_region"] == "hand" and row["verdict"] == "within"
    assert not pd.isna(row["margin_pct"])
    assert "safety (hand recorded, contact area 1.96 cm^2): 1 within, 0 over" in done.stdout
