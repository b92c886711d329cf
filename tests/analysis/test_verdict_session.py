"""Safety verdicts of a session recorded on the emulated rig (``hilrig record`` as a lab runs
it): the hand the scenario names is recorded, and the same session analysed as a hand and as a
chest gives each region's limits and the margins that follow from its force."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from hilrig.analysis import read_dataset
from hilrig.cli import app
from hilrig.recording import inspect
from hilrig.world.body import body_region

HILRIG = Path(sys.executable).with_name("hilrig")
SECONDS = 2.0 + 2 * (0.05 + 0.03) / 0.1 + 1.0 + 0.5  # the default hand, once


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("verdict") / "hand.mcap"
    args = [str(HILRIG), "record", "--subject", "S003", "--scenario", "hand-contact"]
    args += ["--scenario-set", "period_s=none", "--trajectory", "hold"]
    args += ["--duration", str(SECONDS), "--out", str(out)]
    # the timeout includes the wait for the machine's other sessions (make test beside another)
    done = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return out, done.stdout


def test_record_names_the_scenario_s_region_and_prints_the_verdict(
    session: tuple[Path, str],
) -> None:
    out, stdout = session
    metadata = inspect(out).session_info()
    assert metadata is not None and metadata.body_region == "hand"
    assert metadata.contact_area_cm2 is None
    line = stdout.splitlines()[-1]
    assert line.startswith("safety (hand recorded, contact area 1.96 cm^2): 1 within, 0 over; ")


@pytest.mark.parametrize("region", ["hand", "chest"])
def test_a_region_s_limits_and_the_margins_its_force_gives(
    session: tuple[Path, str], region: str, tmp_path: Path
) -> None:
    out, _ = session
    root = tmp_path / "dataset"
    result = CliRunner().invoke(
        app, ["analyze", str(out), "--body-region", region, "-o", str(root)]
    )
    assert result.exit_code == 0, result.output
    assert (
        f"safety ({region} from --body-region, contact area 1.96 cm^2): 1 within" in result.stdout
    )
    rows = read_dataset(root)
    row = rows[rows["group"] == "cartesian"].iloc[0]
    limits = body_region(region)
    assert row["body_region"] == region
    assert row["transient_limit_n"] == 2 * limits.quasi_static_force_n
    assert row["quasi_static_limit_n"] == limits.quasi_static_force_n
    k = limits.spring_constant_n_m
    assert row["energy_j"] == pytest.approx(row["peak_force_n"] ** 2 / (2 * k))
    margins = [
        (row["transient_limit_n"] - row["transient_peak_n"]) / row["transient_limit_n"],
        (limits.quasi_static_force_n - row["quasi_static_peak_n"]) / limits.quasi_static_force_n,
        (2 * limits.quasi_static_pressure_n_cm2 - row["transient_peak_n"] / 1.96)
        / (2 * limits.quasi_static_pressure_n_cm2),
        (limits.quasi_static_pressure_n_cm2 - row["quasi_static_peak_n"] / 1.96)
        / limits.quasi_static_pressure_n_cm2,
    ]
    assert row["margin_pct"] == pytest.approx(100 * min(margins))
    assert 0.5 < row["effective_mass_kg"] < 20 and row["reduced_mass_kg"] < limits.effective_mass_kg
    assert row["verdict"] == "within"
    joints = rows[rows["group"] == "joint"]
    assert joints.empty or pd.isna(joints["verdict"]).all()
    assert np.isfinite(row["speed_limit_m_s"])
