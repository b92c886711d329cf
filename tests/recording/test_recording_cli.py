"""``hilrig info | recover | export`` on real files."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq
from mcap.reader import make_reader
from recording_helpers import Written
from typer.testing import CliRunner

from hilrig.cli.app import app
from hilrig.cli.recording import info_command  # noqa: F401  (registers the commands)
from hilrig.recording import load

runner = CliRunner()


def test_info_shows_session_topics_rates_and_completeness(small_session: Written) -> None:
    result = runner.invoke(app, ["info", str(small_session.path)])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "complete" in out and "TRUNCATED" not in out
    assert "S012" in out and "adaptive" in out and "2026-01-01T00:00:00.000000000Z" in out
    for line in out.splitlines():
        if "/ft/wrist" in line:
            assert "geometry_msgs/msg/WrenchStamped" in line
            assert "1,200" in line and "1000.0" in line
    assert "attachment robot.urdf (application/xml" in out


def test_info_says_a_cut_file_is_truncated(small_session: Written, tmp_path: Path) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(small_session.path.read_bytes()[:300_000])
    result = runner.invoke(app, ["info", str(cut)])
    assert result.exit_code == 1  # read, but unfinished
    assert "TRUNCATED" in result.output
    assert "unfinished recording" in result.output


def test_recover_prints_what_was_kept_and_lost(small_session: Written, tmp_path: Path) -> None:
    cut, fixed = tmp_path / "cut.mcap", tmp_path / "fixed.mcap"
    cut.write_bytes(small_session.path.read_bytes()[:300_000])
    result = runner.invoke(app, ["recover", str(cut), "-o", str(fixed)])
    assert result.exit_code == 1, result.output  # written; the source was unfinished
    assert f"wrote {fixed}" in result.output
    assert "kept " in result.output and "were lost" in result.output
    with open(fixed, "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) > 0


def test_export_parquet_holds_the_loaded_columns(small_session: Written, tmp_path: Path) -> None:
    result = runner.invoke(app, ["export", str(small_session.path), "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    frames = load(small_session.path)
    for topic, frame in frames.items():
        name = topic.strip("/").replace("/", ".")
        table = pq.read_table(tmp_path / f"{name}.parquet").to_pandas()
        expected = frame.reset_index()
        pd.testing.assert_frame_equal(table, expected, check_categorical=False)
    metadata = json.loads((tmp_path / "metadata.json").read_text())
    assert metadata["session"]["subject_id"] == "S012"


def test_export_csv_has_one_row_per_message(small_session: Written, tmp_path: Path) -> None:
    args = ["export", str(small_session.path), "--format", "csv", "--out", str(tmp_path)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    table = pa_csv.read_csv(tmp_path / "controller.state.csv")
    assert table.num_rows == 1200
    assert table.column_names[:4] == [
        "log_time_ns",
        "publish_time_ns",
        "sequence",
        "header.stamp_ns",
    ]
    assert table.column("controller").to_pylist()[0] == "adaptive"
