"""``hilrig replay`` as researchers run it: outputs, the summary, --verify's exit status, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from replay_helpers import EXAMPLE, tampered_copy
from typer.testing import CliRunner

from hilrig.cli import app
from hilrig.errors import ReplayError
from hilrig.replay import job
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
    assert ok.stdout.splitlines()[-1].startswith("OK: largest difference ")  # rounding only
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
            "no --controller, --set, --sweep, --out, --resample, --jobs or --rig\n",
        ),
        (
            ["-o", str(existing)],
            f"error: {existing}: already exists; refusing to overwrite it\n",
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


def _refused(args: list[str]) -> str:
    """stderr of a ``hilrig replay`` that must fail in one line with status 2, printing nothing."""
    result = runner.invoke(app, ["replay", *args])
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert result.stderr.count("\n") == 1, result.stderr
    return result.stderr


def test_outputs_are_all_checked_before_any_work_and_none_is_left_half_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    ok, file = tmp_path / "ok.parquet", tmp_path / "file"
    file.write_text("")
    missing = tmp_path / "missing" / "x.mcap"
    stderr = _refused([str(EXAMPLE), "-c", "fixed", "-o", str(ok), "-o", str(missing)])
    assert stderr == f"error: {missing}: folder {missing.parent} does not exist\n"
    stderr = _refused([str(EXAMPLE), "-c", "fixed", "-o", str(ok), "-o", str(file / "x.mcap")])
    assert stderr == f"error: {file / 'x.mcap'}: {file} is not a folder\n"
    stderr = _refused([str(EXAMPLE), "-c", "fixed", "-o", str(ok), "-o", str(ok)])
    assert stderr == f"error: {ok}, {ok}: the same output is named twice\n"
    assert list(tmp_path.iterdir()) == [file]

    def failing(*args: object, **kwargs: object) -> None:
        raise ReplayError(f"{tmp_path / 'r.mcap'}: the disk is full")

    monkeypatch.setattr(job, "mcap_into", failing)  # the second output fails while written
    stderr = _refused([str(EXAMPLE), "-c", "fixed", "-o", str(ok), "-o", str(tmp_path / "r.mcap")])
    assert stderr == f"error: {tmp_path / 'r.mcap'}: the disk is full\n"
    assert list(tmp_path.iterdir()) == [file]  # no ok.parquet, no temporaries


def test_parameters_that_make_the_filter_non_finite_are_refused_before_the_replay() -> None:
    stderr = _refused([str(EXAMPLE), "-c", "adaptive", "--set", "adaptive.m=1e-300"])
    assert stderr == (
        "error: run adaptive.m=1e-300: m = 1e-300, b_d = 150, k_d = 300 on axis 0: "
        "dt*(b_d + k_d)/m = 9e+299 at dt = 0.002 s must be <= 1e+06, or the discretised filter "
        "loses its precision and overflows\n"
    )


def test_a_result_that_is_not_finite_is_refused_and_not_written(tmp_path: Path) -> None:
    csv, out = tmp_path / "push.csv", tmp_path / "r.parquet"
    t = np.arange(3000) * 0.002
    pd.DataFrame({"t": t, "fx": np.where(t > 0.2, 1e308, 0.0), "fy": 0.0, "fz": 0.0}).to_csv(
        csv, index=False
    )
    sets = ["--set", "fixed.m=1", "--set", "fixed.b_d=0.1", "--set", "fixed.k_d=1"]
    stderr = _refused([str(csv), "-c", "fixed", *sets, "-o", str(out)])
    assert stderr == (
        "error: run fixed.m=1.b_d=0.1.k_d=1 (fixed): column offset_x is inf at tick 1491 "
        "(t = 2.982 s), its first value that is not finite; the result is refused\n"
    )
    assert list(tmp_path.iterdir()) == [csv]


def test_options_that_do_not_apply_are_refused(tmp_path: Path) -> None:
    cases = [
        (
            ["--start", "2"],
            "error: --start: only for --rig (playing FILE into a live session); an offline "
            "replay or --verify takes the whole input\n",
        ),
        (
            ["--verify", "--duration", "1", "--rate", "500"],
            "error: --rate, --duration: only for --rig (playing FILE into a live session); an "
            "offline replay or --verify takes the whole input\n",
        ),
        (
            ["--resample"],
            f"error: {EXAMPLE}: --resample is for CSV and Parquet tables; a recording is "
            "replayed at its loop's period as it is\n",
        ),
        (
            ["--rig", "emulated", "--rate", "0"],
            "error: --rate 0: the loop rate must be a finite number of Hz > 0\n",
        ),
        (
            ["--rig", "emulated", "--start", "nan"],
            "error: --start nan: must be a finite time of FILE >= 0 s\n",
        ),
        (
            ["--rig", "emulated", "--duration", "-1"],
            "error: --duration -1: must be a finite time > 0 s\n",
        ),
    ]
    for args, message in cases:
        assert _refused([str(EXAMPLE), *args]) == message, args


def test_a_sweep_too_big_is_refused_at_once() -> None:
    stderr = _refused(
        [
            str(EXAMPLE),
            *("-c", "adaptive"),
            *("--sweep", "adaptive.a1=1:40:10000", "--sweep", "adaptive.beta=1:29:10000"),
        ]
    )
    assert stderr == (
        "error: --sweep: 100000000 runs (adaptive: 10000 x 10000), more than the limit of "
        "10000; sweep fewer values\n"
    )


def test_a_parquet_table_timed_by_timestamps_replays_over_its_own_duration(tmp_path: Path) -> None:
    path = tmp_path / "push.parquet"
    t = pd.date_range("2026-01-01", periods=500, freq="2ms")
    pd.DataFrame({"t": t, "fx": 1.0, "fy": 0.0, "fz": 0.0}).to_parquet(path)
    result = runner.invoke(app, ["replay", str(path), "-c", "fixed"])
    assert result.exit_code == 0, result.output
    assert "over 1.000 s of" in result.stdout  # 500 ticks of 2 ms
