"""Run the paper's simulation experiments and write tables and figures into one directory:
every output checked before any work, written beside its place and moved in all at once."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hilrig.control import PAPER_DT_S
from hilrig.errors import OutputError
from hilrig.outputs import check_new_file, new_files
from hilrig.paper.experiments import PaperResults, run_all
from hilrig.paper.plots import figure_names, write_plots
from hilrig.paper.report import (
    TABLE_NAMES,
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


def output_names() -> tuple[str, ...]:
    """The files :func:`reproduce` writes: the tables, then the figures."""
    return (*TABLE_NAMES, *figure_names())


def reproduce(out_dir: Path, *, dt_s: float = PAPER_DT_S) -> Reproduction:
    """Run sections 2.1 and 3.4 at dt_s (s); write the tables and figures into out_dir.

    Writes paper-table.{md,csv}, paper-sweeps.{md,csv} and the PNG figures (see ``plots``;
    :func:`output_names`); out_dir is created if needed. Raises OutputError before any work if
    one of them exists (nothing is overwritten) or cannot be written; after a failure nothing
    is left (:func:`hilrig.outputs.new_files`).
    """
    finals = tuple(out_dir / name for name in output_names())
    try:
        for final in finals:
            check_new_file(final, create_folder=True)
    except NotADirectoryError:  # a file where one of its folders should be
        raise OutputError(f"{out_dir}: a file stands where this folder should be") from None
    with new_files(*finals, create_folders=True) as temporaries:
        paths = dict(zip(output_names(), temporaries, strict=True))
        results = run_all(dt_s=dt_s)
        table, sweeps = comparison_table(results), sweep_table(results)
        sections = (*display_sections(table), sweep_section(sweeps))
        write_tables(table, sweeps, paths)
        write_plots(results, paths)
    return Reproduction(results, sections, finals)
