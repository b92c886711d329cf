"""Run the paper's simulation experiments and write tables and figures into one directory."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hilrig.control import PAPER_DT_S
from hilrig.paper.experiments import PaperResults, run_all
from hilrig.paper.plots import write_plots
from hilrig.paper.report import (
    Section,
    comparison_table,
    display_sections,
    sweep_section,
    sweep_table,
    write_tables,
)


@dataclass(frozen=True)
class Reproduction:
    """The results, their display sections and every file written (tables, then figures)."""

    results: PaperResults
    sections: tuple[Section, ...]
    files: tuple[Path, ...]


def reproduce(out_dir: Path, *, dt_s: float = PAPER_DT_S) -> Reproduction:
    """Run sections 2.1 and 3.4 at dt_s (s); write the tables and figures into out_dir.

    Writes paper-table.{md,csv}, paper-sweeps.{md,csv} and the PNG figures (see ``plots``);
    out_dir is created if needed.
    """
    results = run_all(dt_s=dt_s)
    table, sweeps = comparison_table(results), sweep_table(results)
    sections = (*display_sections(table), sweep_section(sweeps))
    files = (*write_tables(table, sweeps, out_dir), *write_plots(results, out_dir))
    return Reproduction(results, sections, files)
