"""``hilrig replay`` as researchers run it: outputs, the summary, --verify's exit status, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from replay_helpers import EXAMPLE, tampered_copy
from typer.testing import CliRunner

from hilrig.cli import app
from hilrig.replay.outputs import load_results

runner = CliRunner()


def test_controllers_sets_and_sweeps_to_parquet_and_mcap_with_a_summary(tmp_path: Path) -> None:
    table, mcap = tmp_path / "r.parquet", tmp_path / "r.mcap"
    args = ["replay", str(EXAMPLE), "-c", "adaptive", "-c", "stiff=fixed"]
    args += ["--set", "adaptive.a1=10", "--sweep", "stiff.k_d=200:400:3"]
    result = runner.invoke(app, [*args, "-o", str(table), "-o", str(mcap)])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert f"wrote {table}" in out and f"wrote {mcap}" in out
    assert "max |offset| (x y z: mm, joints: mrad)" in out
    frame, runs = load_results(table)
    assert list(runs) == ["adaptive.a1=10", "stiff.k_d=200", "stiff.k_d=300", "stiff.k_d=400"]
    for name in runs:
        peak_mm = 1000 * np.abs(frame.loc[frame["run"] == name, "offset_x"]).max()
        line = next(line for line in out.splitlines() if f" {name} " in line)
        assert f"{peak_mm:.2f}" in line
    assert mcap.stat().st_size > 0


def test_a_table_input_and_its_resampling_note(tmp_path: Path) -> None:
    csv = tmp_path / "push.csv"
    t = np.array([0.0, 0.001, 0.002, 0.0035, 0.0045])
    pd.DataFrame({"t": t, "fx": 1.0, "fy": 0.0, "fz": 0.0}).to_csv(csv, index=False)
    refused = runner.invoke(app, ["replay", str(csv), "-c", "fixed"])
    assert refused.exit_code == 2
    assert refused.stderr.startswith(f"error: {csv}: column t, row 3 (line 5): non-uniform")
    assert refused.stderr.count("\n") == 1
    result = runner.invoke(app, ["replay", str(csv), "-c", "fixed", "--resample"])
    assert result.exit_code == 0, result.output
    assert f"note: {csv}: resampled onto a uniform 0.001 s grid" in result.stderr


def test_verify_exits_0_on_a_recording_and_1_on_a_tampered_copy(tmp_path: Path) -> None:
    ok = runner.invoke(app, ["replay", str(EXAMPLE), "--verify"])
    assert ok.exit_code == 0, ok.output
    assert ok.stdout.splitlines()[-1] == "OK: largest difference 0 (tolerance 1e-12)"
    bad = runner.invoke(app, ["replay", str(tampered_copy(tmp_path)), "--verify"])
    assert bad.exit_code == 1
    assert bad.stdout.splitlines()[-1].startswith("FAILED: largest difference 10 ")


def test_mistakes_are_one_line_errors_with_status_2(tmp_path: Path) -> None:
    existing = tmp_path / "old.parquet"
    existing.write_bytes(b"")
    cases = [
        (["--set", "adaptive.a1"], "error: --set adaptive.a1: expected NAME.PARAM=VALUE\n"),
        (
            ["--verify", "-c", "fixed"],
            "error: --verify replays the recorded controller: it takes "
            "no --controller, --set, --sweep, --out or --resample\n",
        ),
        (
            ["-o", str(existing)],
            f"error: --out {existing}: already exists; refusing to overwrite it\n",
        ),
        (
            ["-o", str(tmp_path / "r.xlsx")],
            f"error: --out {tmp_path / 'r.xlsx'}: unknown output "
            "type; known: .parquet, .pq, .mcap\n",
        ),
    ]
    for args, message in cases:
        result = runner.invoke(app, ["replay", str(EXAMPLE), *args])
        assert result.exit_code == 2, args
        assert result.stderr == message
        assert result.stdout == ""
