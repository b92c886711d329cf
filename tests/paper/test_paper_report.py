"""``hilrig paper``: the files it writes, the tables' contents, and the command itself."""

import os
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

import hilrig.paper.reproduce
from hilrig.cli import run
from hilrig.cli.app import app
from hilrig.paper.experiments import OFFSET_DISPLAY, PUBLISHED_CHANGES, PUBLISHED_PEAKS
from hilrig.paper.reproduce import Reproduction, reproduce

TABLES = ("paper-table.md", "paper-table.csv", "paper-sweeps.md", "paper-sweeps.csv")
FIGURES = (
    "fig04a-mass-sweep.png",
    "fig04b-damping-sweep.png",
    "fig04c-stiffness-sweep.png",
    "fig10-end-effector-force.png",
    "fig11-end-effector-damping.png",
    "fig12-end-effector-stiffness.png",
    "fig13-offset-x.png",
    "fig14-offset-y.png",
    "fig15-offset-z.png",
    "fig18-joint-torque.png",
    "fig19-joint-damping.png",
    "fig20-joint-stiffness.png",
    "fig21-offset-joint1.png",
    "fig22-offset-joint2.png",
)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def reproduction(tmp_path_factory: pytest.TempPathFactory) -> Reproduction:
    return reproduce(tmp_path_factory.mktemp("paper") / "nested" / "out")


def test_reproduce_writes_every_table_and_figure(reproduction: Reproduction) -> None:
    out_dir = reproduction.files[0].parent
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(TABLES + FIGURES)
    assert [p.name for p in reproduction.files] == [*TABLES, *FIGURES]
    for name in FIGURES:
        assert (out_dir / name).read_bytes().startswith(PNG_MAGIC)


def test_csv_table_holds_our_peaks_beside_the_papers(reproduction: Reproduction) -> None:
    table = pd.read_csv(reproduction.files[0].parent / "paper-table.csv")
    results = reproduction.results
    assert len(table) == 3 * len(results.peaks) + 2 * len(results.changes)
    offsets = table[table["quantity"] == "max offset"]
    rows = {(r["experiment"], r["axis"], r["law"]): r for r in offsets.to_dict("records")}
    assert len(rows) == len(results.peaks)
    for peak in results.peaks:
        row = rows[peak.experiment.value, peak.axis, peak.law.value]
        unit, scale = OFFSET_DISPLAY[peak.experiment]
        assert row["unit"] == unit
        assert row["ours"] == pytest.approx(peak.max_abs_offset * scale, rel=1e-12)
        assert row["difference"] == pytest.approx(row["ours"] - row["paper"], rel=1e-12)
    assert offsets["paper"].notna().all()


def test_markdown_table_contains_the_papers_numbers(reproduction: Reproduction) -> None:
    text = (reproduction.files[0].parent / "paper-table.md").read_text(encoding="utf-8")
    for peak in PUBLISHED_PEAKS:
        unit, scale = OFFSET_DISPLAY[peak.experiment]
        decimals = 2 if unit == "mm" else 4
        assert f"| {peak.max_abs_offset * scale:.{decimals}f} |" in text
        if peak.time_of_max_s is not None:
            assert f"| {peak.time_of_max_s:.3f} |" in text
    for change in PUBLISHED_CHANGES:
        assert f"| {change.offset_change_pct:.2f} |" in text
        assert f"| {change.response_time_change_pct:.2f} |" in text
    assert "## Notes" in text and "since onset" in text


def test_sweep_csv_has_one_row_per_case(reproduction: Reproduction) -> None:
    sweeps = pd.read_csv(reproduction.files[0].parent / "paper-sweeps.csv")
    assert len(sweeps) == 15
    assert sweeps["steady_state_mm"].to_numpy() == pytest.approx(
        sweeps["static_offset_mm"].to_numpy(), rel=1e-5
    )


def test_paper_command_writes_files_and_prints_the_table_in_80_columns(
    tmp_path: Path,
) -> None:
    out = tmp_path / "a[red]b"  # a file name is shown as it is, never read as markup
    result = CliRunner().invoke(app, ["paper", "--out", str(out)], env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == sorted(TABLES + FIGURES)
    assert "end effector: max offset in mm" in result.output
    assert f"  {out / 'paper-table.md'}\n" in result.output
    lines = result.output.splitlines()
    assert max(len(line) for line in lines if str(out) not in line) <= 80
    assert "…" not in result.output
    # every number of the changes table, whole, on the line of its axis and comparison
    table = pd.read_csv(out / "paper-table.csv")
    changes = table[table["quantity"] == "offset change"]
    for row in changes.itertuples():
        numbers = [f"{v:.2f}" for v in (row.ours, row.paper, row.paper_recomputed) if v == v]
        assert any(all(n in line.split() for n in numbers) for line in lines), row


def test_paper_refuses_an_existing_output_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def no_work(**kwargs: object) -> None:
        raise AssertionError("the simulations ran")

    monkeypatch.setattr(hilrig.paper.reproduce, "run_all", no_work)
    (tmp_path / "fig13-offset-x.png").write_bytes(b"an earlier figure")
    assert run(["paper", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"error: {tmp_path / 'fig13-offset-x.png'}: already exists; refusing to overwrite it; "
        "choose another --out, or move the earlier outputs away\n"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["fig13-offset-x.png"]
    assert (tmp_path / "fig13-offset-x.png").read_bytes() == b"an earlier figure"
    (tmp_path / "afile").write_bytes(b"")
    assert run(["paper", "--out", str(tmp_path / "afile" / "out")]) == 2
    assert capsys.readouterr().err.startswith(
        f"error: {tmp_path / 'afile' / 'out' / 'paper-table.md'}: {tmp_path / 'afile'} is not a "
        "folder; "
    )


def test_an_unwritable_folder_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)  # as for a user, not root
    assert run(["paper", "--out", str(tmp_path / "new")]) == 2
    assert capsys.readouterr().err == (
        f"error: {tmp_path / 'new' / 'paper-table.md'}: folder {tmp_path} is not writable; "
        "choose another --out, or move the earlier outputs away\n"
    )
    assert not list(tmp_path.iterdir())


def test_a_paper_run_that_fails_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(*args: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(hilrig.paper.reproduce, "write_plots", broken)
    with pytest.raises(OSError, match="disk full"):
        reproduce(tmp_path / "new" / "out")
    assert not list(tmp_path.iterdir())  # no table, no temporary, no folder
