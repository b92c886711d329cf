"""docs/benchmarks.md and the README's table are what ``python -m benchmarks report`` writes
from the committed results, and each figure stands beside its own run's calibration."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from benchmarks import report

ROOT = Path(__file__).resolve().parents[1]


def test_committed_pages_equal_what_the_results_give() -> None:
    page, table = report.render(report.load_runs())
    assert report.PAGE.read_text() == page, "run: python -m benchmarks report"
    assert report.README.read_text() == report.with_table(report.README.read_text(), table)


def test_the_check_command_passes_on_the_committed_pages() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "benchmarks", "report", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


def _run(folder: Path, stamp: str, suites: dict[str, list[tuple[str, float]]]) -> None:
    results = [
        {"suite": s, "name": n, "value": v, "unit": "u", "target": "", "passed": None, "detail": {}}
        for s, rows in suites.items()
        for n, v in rows
    ]
    data = {"when_utc": stamp, "machine": {"cores": 2}, "suites": list(suites), "results": results}
    (folder / f"{stamp[:16].replace(':', '-')}.json").write_text(json.dumps(data))


def test_each_suite_comes_from_its_newest_run_with_that_runs_calibration(tmp_path: Path) -> None:
    lfilter = "lfilter fixed (reference), median / best run"
    _run(tmp_path, "2026-01-01T10:00:00", {"control": [(lfilter, 50.0)], "study": [("a", 1.0)]})
    _run(tmp_path, "2026-01-02T10:00:00", {"control": [(lfilter, 80.0), ("step", 2.0)]})
    (tmp_path / "latest.json").write_text("not read")
    runs = report.load_runs(tmp_path)
    newest = report.newest_by_suite(runs)
    assert {k: v.when_utc[:10] for k, v in newest.items()} == {
        "control": "2026-01-02",
        "study": "2026-01-01",
    }
    assert report.calibration(newest["study"])[0] == "scipy lfilter, median: 50 u"
    assert report.calibration(newest["control"])[0] == "scipy lfilter, median: 80 u"
    assert report.calibration(newest["control"])[1] == "mcap_ros2 writer: not measured in this run"


def test_numbers_keep_four_significant_digits() -> None:
    assert [report.number(v) for v in (41_862_345.0, 0.3321, 1234.0, 0.0, 2e-5)] == [
        "41,860,000",
        "0.3321",
        "1234",
        "0",
        "2e-05",
    ]
