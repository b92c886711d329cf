"""``hilrig report``: a study's report, one self-contained HTML file."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app

if TYPE_CHECKING:
    from hilrig.study.assemble import ReportOptions


@app.command("report")
def report_command(
    root: Annotated[
        Path,
        typer.Argument(
            metavar="DIR", help="The study's folder of recordings (hilrig study index)."
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="The report to write (.html).", show_default=False)
    ],
    baseline: Annotated[
        str | None,
        typer.Option(
            help="Condition the others are compared against (default: study.toml's, else "
            "fixed, else the first)."
        ),
    ] = None,
    delta: Annotated[
        float, typer.Option(help="Collision threshold, N (Cartesian norm) and N*m (joints).")
    ] = 0.2,
    body_region: Annotated[
        str | None,
        typer.Option(
            help="ISO/TS 15066 body region for the safety margin, over each recording's own."
        ),
    ] = None,
    confidence: Annotated[
        float, typer.Option(help="Confidence level of the bootstrap intervals.")
    ] = 0.95,
    resamples: Annotated[int, typer.Option(help="Bootstrap resamples.")] = 9999,
    seed: Annotated[int, typer.Option(help="Seed of the bootstrap's random numbers.")] = 0,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing report.")] = False,
) -> None:
    """Statistics across the study's volunteers and its figures, as one HTML file that opens
    offline: design, catalogue, exclusions, per-controller distributions with every subject,
    paired or unpaired comparisons, representative collisions (docs/study.md)."""
    from rich.console import Console

    from hilrig.analysis import EventConfig
    from hilrig.analysis.verdict import VerdictConfig
    from hilrig.cli.progress import phase_bar
    from hilrig.errors import StudyError
    from hilrig.outputs import check_new_file
    from hilrig.study.assemble import ReportOptions, assemble
    from hilrig.study.figures import figure_count
    from hilrig.study.observations import AnalysisSettings
    from hilrig.study.report_html import write_report

    if out.suffix.lower() not in (".html", ".htm"):
        raise StudyError(f"--out {out}: a report is an .html file")
    if not 0 < confidence < 1:
        raise StudyError(f"--confidence {confidence}: must be between 0 and 1")
    if resamples < 100:
        raise StudyError(f"--resamples {resamples}: at least 100")
    check_new_file(out, overwrite=overwrite)
    settings = AnalysisSettings(EventConfig(delta=delta), VerdictConfig(body_region))
    options = ReportOptions(baseline, settings, confidence, resamples, seed)
    console = Console(highlight=False, stderr=True)
    with phase_bar(console, enabled=console.is_terminal) as bar:
        report = assemble(root, options, _command(root, out, options, delta), step=bar)
        total = figure_count(report)
        drawn = iter(range(1, total + 1))
        written = write_report(
            report,
            out,
            overwrite=overwrite,
            progress=None if bar is None else lambda _: bar("figures", next(drawn), total),
        )
    excluded = int((report.catalogue["excluded"] != "").sum())
    Console(highlight=False).print(
        f"wrote {written}: {len(report.catalogue) - excluded} sessions of "
        f"{report.observations['subject'].nunique()} subjects, {excluded} excluded",
        soft_wrap=True,
        markup=False,
    )


def _command(root: Path, out: Path, options: ReportOptions, delta: float) -> str:
    """The command that makes this report again (folder and file by name only: a path may
    name a person)."""
    from hilrig.study.assemble import ReportOptions

    words = ["hilrig", "report", root.name or str(root), "-o", out.name]
    if options.baseline:
        words += ["--baseline", options.baseline]
    if delta != 0.2:
        words += ["--delta", repr(delta)]
    if options.analysis.safety.body_region:
        words += ["--body-region", options.analysis.safety.body_region]
    defaults = ReportOptions()
    for name in ("confidence", "resamples", "seed"):
        if getattr(options, name) != getattr(defaults, name):
            words += [f"--{name}", str(getattr(options, name))]
    return shlex.join(words)
