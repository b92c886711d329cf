"""``hilrig analyze``: collision events, metrics and comparison tables of sessions and replays."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app

if TYPE_CHECKING:
    import pandas as pd
    from rich.console import Console

    from hilrig.analysis import Analysis


@app.command("analyze")
def analyze_command(
    paths: Annotated[
        list[Path],
        typer.Argument(
            help="MCAP sessions, replay results (.parquet) and/or folders of them.",
            show_default=False,
        ),
    ],
    baseline: Annotated[
        str | None,
        typer.Option(help="Run (controller) to compare against; default: fixed, else the first."),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="Write the comparison to a .csv or .parquet file, or the per-event metrics of"
            " every input to a Parquet dataset in this folder (a path without a suffix).",
        ),
    ] = None,
    delta: Annotated[
        float, typer.Option(help="Collision threshold, N (Cartesian norm) and N*m (joints).")
    ] = 0.2,
    debounce_s: Annotated[
        float, typer.Option("--debounce-s", help="Least time above delta of an event, s.")
    ] = 0.02,
    merge_gap_s: Annotated[
        float, typer.Option("--merge-gap-s", help="Events closer than this merge, s.")
    ] = 0.05,
    body_region: Annotated[
        str | None,
        typer.Option(
            help="ISO/TS 15066 body region the robot hit (over the recording's), for the safety "
            "verdicts: skull, face, neck, back, chest, abdomen, pelvis, upper-arm, lower-arm, "
            "hand, thigh, lower-leg.",
        ),
    ] = None,
    contact_area_cm2: Annotated[
        float | None,
        typer.Option(
            "--contact-area-cm2",
            help="Contact area for the pressure, cm^2 (default: the recording's, else the "
            "standard's probe, 1.96).",
        ),
    ] = None,
    transient_s: Annotated[
        float,
        typer.Option(
            "--transient-s", help="Length of a collision's transient phase, s (docs/safety.md)."
        ),
    ] = 0.5,
    overwrite: Annotated[
        bool,
        typer.Option(
            help="Replace an existing --out file, or the dataset's partitions of the sessions "
            "analysed (never an input)."
        ),
    ] = False,
) -> None:
    """Find collisions in the force channels, measure every run on every axis, compare runs."""
    from rich.console import Console

    from hilrig.analysis import (
        ACROSS_SOURCES,
        EventConfig,
        SourceKind,
        analyze,
        comparison,
        comparison_table,
        dataset_frame,
        default_baseline,
        load_sources,
        runs_of,
        values,
        write_dataset,
        write_table,
    )
    from hilrig.analysis.dataset import check_dataset_root
    from hilrig.analysis.report import check_table_path
    from hilrig.analysis.verdict import VerdictConfig
    from hilrig.errors import AnalysisError

    config = EventConfig(delta=delta, debounce_s=debounce_s, merge_gap_s=merge_gap_s)
    safety = VerdictConfig(body_region, contact_area_cm2, transient_s)
    dataset = out is not None and (out.is_dir() or not out.suffix)
    if out is not None:  # every output checked before any work
        if any(out.resolve() == path.resolve() for path in paths):
            raise AnalysisError(f"--out {out}: is also an input; write the results elsewhere")
        if dataset:
            check_dataset_root(out)
        else:
            check_table_path(out, overwrite=overwrite)
    sources = load_sources(paths, exclude=out)
    names = list(dict.fromkeys(run.name for source in sources for run in source.runs))
    if baseline is not None and baseline not in names:
        raise AnalysisError(f"baseline {baseline!r} is not a run here; runs: {', '.join(names)}")
    analyses = [analyze(s, events=config, safety=safety) for s in sources]
    runs = runs_of(values(analyses))
    chosen = baseline if baseline is not None else default_baseline(runs)
    console = Console(highlight=False)
    if not console.is_terminal:  # keep whole rows when piped
        console = Console(highlight=False, width=160)
    tables = [print_source(console, a, chosen, delta) for a in analyses]
    sessions = [a for a in analyses if a.source.kind is SourceKind.SESSION]
    if len(sessions) > 1:
        long = values(sessions)
        base = chosen if chosen in set(long["run"]) else default_baseline(runs_of(long))
        across = comparison(long, baseline=base, by=ACROSS_SOURCES)
        title = f"{len(sessions)} sessions: mean over events"
        console.print(comparison_table(across, baseline=base, title=title))
        tables.append(across)
    if out is None:
        return
    frame = dataset_frame(analyses) if dataset else None
    if frame is not None and frame.empty:  # a dataset holds events' metrics: none to hold
        inputs = ", ".join(a.source.name for a in analyses)
        line = f"no collision events in {inputs}: nothing written to {out}"
        console.print(line, markup=False, soft_wrap=True)
        return
    if frame is not None:
        written = write_dataset(frame, out, overwrite=overwrite)
    else:
        written = write_table(tables, out, overwrite=overwrite)
    console.print(f"wrote {written}", markup=False, soft_wrap=True)


def print_source(console: Console, analysis: Analysis, baseline: str, delta: float) -> pd.DataFrame:
    """Print a source's events and its runs' comparison (against its own first run when
    ``baseline`` is not among them, as for a session of another controller); return it.

    The printed table keeps the axes that took part in an event (their own |force| above
    ``delta``); the returned one has every axis.
    """
    import pandas as pd
    from rich.markup import escape

    from hilrig.analysis import (
        comparison,
        comparison_table,
        default_baseline,
        events_table,
        runs_of,
        values,
    )
    from hilrig.analysis.report import verdict_line, verdicts_table

    console.print(f"[bold]{escape(analysis.source.name)}[/]")
    console.print(events_table(analysis))
    mine = values([analysis])
    base = baseline if baseline in set(mine["run"]) else default_baseline(runs_of(mine))
    table = comparison(mine, baseline=base)
    loaded = {(m.event, m.axis) for m in analysis.metrics if abs(m.peak_force) > delta}
    axes = {axis for _, axis in loaded}
    shown = [
        axis in axes if pd.isna(event) else (event, axis) in loaded
        for event, axis in zip(table["event"], table["axis"], strict=True)
    ]
    console.print(comparison_table(table[shown], baseline=base, title="comparison"))
    if analysis.verdicts:
        console.print(verdicts_table(analysis))
    console.print(verdict_line(analysis), soft_wrap=True)
    return table
