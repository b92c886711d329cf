"""A sweep's report as one self-contained HTML file: each axis group's metrics against the
swept parameter (:mod:`.report_figures`) and its summary table, inline CSS and SVG.

It shows what the closing tables show (:mod:`.summary`), with the subjects' spread; it is
written whole or not at all (:func:`hilrig.outputs.new_files`), and names folders, runs and
controllers only (a path may name a person).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd
from markupsafe import Markup

from hilrig import __version__
from hilrig.errors import OutputError
from hilrig.replay.specs import ControllerSpec
from hilrig.study.figures import GROUP_LABELS, GROUP_ORDER
from hilrig.study.records import STUDY_METRICS, metric_heading, shown_metric_unit
from hilrig.study.report_html import check_report_path, environment, number, write_html
from hilrig.sweep.driver import SweepSummary
from hilrig.sweep.report_figures import LABELS, OVER, Layout, layout, sweep_figure, with_over

OVERWRITE_FLAG = "--overwrite-report"  # hilrig sweep's option to replace a report
HOW = (
    "Each value is the median over subjects of each subject's mean over its events in every "
    "source, each event counted once, on its loaded axis; the bands and bars span the "
    "subjects' first to third quartile."
)


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def render(summary: SweepSummary, specs: Sequence[ControllerSpec]) -> str:
    """The whole HTML document of ``summary``'s sweep through the runs ``specs``."""
    where = layout(specs)
    by_run = with_over(summary.by_run)
    subjects = summary.by_subject["subject"].nunique()
    counts = ", ".join(
        [_plural(len(specs), "run"), _plural(subjects, "subject"), _plural(summary.tasks, "task")]
    )
    groups = []
    present = set(by_run["group"])
    for group in sorted(present, key=lambda g: (g not in GROUP_ORDER, g)):  # Cartesian first
        rows = by_run[by_run["group"] == group]
        mine = summary.by_subject[summary.by_subject["group"] == group]
        groups.append(_group(group, rows, mine, where))
    runs = [
        {
            "name": spec.name,
            "controller": spec.controller,
            "law": spec.law.value,
            "settings": ", ".join(s.label for s in spec.settings) or "its presets",
        }
        for spec in specs
    ]
    context = {
        "name": summary.root.name or str(summary.root),
        "created_utc": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "version": __version__,
        "counts": counts,
        "how": HOW,
        "runs": runs,
        "groups": groups,
    }
    return environment().get_template("sweep.html.j2").render(context)


def _group(group: str, rows: pd.DataFrame, subjects: pd.DataFrame, where: Layout) -> dict[str, Any]:
    metrics = [m for m in STUDY_METRICS if rows[m].notna().any()]
    columns = ["run", "subjects", "events", "judged", "over"]
    headings = [*columns, *(metric_heading(m, group) for m in metrics)]
    factors = [shown_metric_unit(m, group)[1] for m in metrics]
    table = [
        [str(record["run"]), *(number(int(record[c])) for c in columns[1:])]
        + [number(float(record[m]) * f) for m, f in zip(metrics, factors, strict=True)]
        for record in rows.to_dict("records")
    ]
    figure = sweep_figure(group, rows, subjects, where)
    axis = ", run by run" if where.x is None else f" against {where.x}"
    share = f"; {LABELS[OVER]} in % of those judged" if rows[OVER].notna().any() else ""
    return {
        "id": f"group-{group}",
        "label": GROUP_LABELS.get(group, group),
        "figure": Markup(figure.svg),
        "caption": f"Each metric{axis}{share}.",
        "columns": headings,
        "rows": table,
    }


def check_report(path: Path, *, overwrite: bool = False) -> None:
    """Refuse, before the sweep, a report path that could not be written (OutputError)."""
    if path.suffix.lower() not in (".html", ".htm"):
        raise OutputError(f"--report {path}: a report is an .html file")
    check_report_path(path, overwrite=overwrite, flag=OVERWRITE_FLAG)


def write_sweep_report(
    summary: SweepSummary,
    specs: Sequence[ControllerSpec],
    path: Path,
    *,
    overwrite: bool = False,
) -> Path:
    """Write the HTML report of ``summary`` to ``path``, whole or not at all; an existing file
    is replaced only with ``overwrite`` (OutputError otherwise, before anything is drawn)."""
    return write_html(
        path, lambda: render(summary, specs), overwrite=overwrite, flag=OVERWRITE_FLAG
    )
