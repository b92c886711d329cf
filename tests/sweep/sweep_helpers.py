"""Inputs for the sweep tests: recorded sessions (analysis's writer) and force tables, and the
sweep's command line in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from analysis_helpers import write_session  # re-exported for the sweep tests

HILRIG = Path(sys.executable).with_name("hilrig")
#: Three parameter sets of the adaptive law (the sweep's grid in most tests).
SWEEP = ("-c", "adaptive", "--sweep", "adaptive.a1=5,10,20")


def sessions(folder: Path, count: int = 2, duration_s: float = 6.0) -> list[Path]:
    """``count`` short recorded sessions (the paper's collision at 500 Hz) in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    return [
        write_session(
            folder / f"S{n:03d}.mcap",
            subject_id=f"S{n:03d}",
            session_id=f"20260101-00000{n}-S{n:03d}",
            duration_s=duration_s,
        )
        for n in range(1, count + 1)
    ]


def force_table(path: Path, duration_s: float, *, seed: int = 0) -> Path:
    """A 1 kHz force table (t, fx fy fz, tau1..tau6): noise and a 1.5 s push every 10 s."""
    rng = np.random.default_rng(seed)
    ticks = round(duration_s * 1000)
    force = rng.normal(scale=0.05, size=(ticks, 9))
    push = np.sin(np.linspace(0.0, np.pi, 1500))
    for start in range(2000, ticks - 1500, 10_000):
        force[start : start + 1500, rng.integers(9)] += rng.uniform(2.0, 8.0) * push
    names = ["fx", "fy", "fz", *(f"tau{j}" for j in range(1, 7))]
    frame = pd.DataFrame({"t": np.arange(ticks) / 1000.0} | dict(zip(names, force.T, strict=True)))
    frame.to_parquet(path)
    return path


def hilrig(*args: str, timeout: float = 120, columns: int = 80) -> subprocess.CompletedProcess[str]:
    """``hilrig ARGS`` in a subprocess, its output captured (``columns`` wide)."""
    env = os.environ | {"COLUMNS": str(columns)}
    return subprocess.run(
        [str(HILRIG), *args], capture_output=True, text=True, timeout=timeout, check=False, env=env
    )
