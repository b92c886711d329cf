"""A study's report as one self-contained HTML file: inline CSS and SVG, nothing fetched.

:func:`render` fills ``templates/report.html.j2`` (jinja2, autoescaped, strict) with tables of
preformatted text and the figures of :mod:`hilrig.study.figures`; :func:`write_report` writes
it whole or not at all through :func:`hilrig.outputs.new_files`. Values are shown in the units
of :func:`hilrig.analysis.report.shown_unit` (offsets in mm) with three significant digits.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup

from hilrig.errors import OutputError
from hilrig.outputs import check_new_file, new_files
from hilrig.study.figures import (
    GROUP_LABELS,
    conditions_of,
    metrics_of,
    report_figures,
)
from hilrig.study.records import StudyReport, metric_heading, shown_metric_unit

Progress = Callable[[str], None]
Row = dict[str, Any]
MISSING = "\u2013"  # en dash: no value
MINUS = "\u2212"  # the minus sign, as numbers are typeset
TIMES = "\u00d7"  # multiplication sign
SIGNIFICANCE = 0.05  # adjusted p below this is highlighted
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def number(value: object, digits: int = 3, *, signed: bool = False) -> str:
    """``value`` with ``digits`` significant digits (whole numbers of that size or more as they
    are, below 0.0001 as a power of ten), a typographic minus; :data:`MISSING` if missing."""
    if value is None or isinstance(value, str):
        return MISSING if not value else str(value)
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return f"{int(value):,}".replace("-", MINUS)
    x = float(value)  # type: ignore[arg-type]
    if math.isnan(x):
        return MISSING
    sign = "+" if signed and x > 0 else ""
    if math.isinf(x) or x == 0:
        text = f"{sign}{x:g}"
    elif abs(x) < 1e-4:
        mantissa, exponent = f"{x:.{digits - 1}e}".split("e")
        text = f"{sign}{mantissa}{TIMES}10{str(int(exponent)).translate(_SUPERSCRIPT)}"
    else:
        decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
        text = f"{sign}{x:,.{decimals}f}"
    return text.replace("-", MINUS)


def p_text(p: float) -> str:
    """A p-value with two significant digits, "<0.001" below that."""
    if math.isnan(p):
        return MISSING
    return "<0.001" if p < 1e-3 else number(p, 2)


def _time(value: object) -> str:
    try:
        stamp = pd.Timestamp(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return str(value)
    return str(value) if pd.isna(stamp) else stamp.strftime("%Y-%m-%d %H:%M")


def _text(value: object) -> str:
    """``value`` as text, "" for None or NaN (a missing cell)."""
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)


def _flags(text: object) -> list[str]:
    return [f.strip() for f in _text(text).split(",") if f.strip()]


def _params(text: object) -> str:
    try:
        params = json.loads(_text(text))
    except ValueError:
        return _text(text)
    if not isinstance(params, dict):
        return str(params)
    return ", ".join(f"{k} = {v}" for k, v in params.items())


def _spanned(rows: list[Row]) -> list[Row]:
    """Set ``span`` on the first row of each metric (its rowspan), 0 on the others."""
    for index, row in enumerate(rows):
        first = index == 0 or rows[index - 1]["metric"] != row["metric"]
        row["span"] = sum(r["metric"] == row["metric"] for r in rows) if first else 0
    return rows


def _ordered(
    frame: pd.DataFrame, group: str, metrics: list[str], conditions: list[str]
) -> pd.DataFrame:
    shown = frame[frame["group"] == group]
    metric_rank = {m: i for i, m in enumerate(metrics)}
    condition_rank = {c: i for i, c in enumerate(conditions)}
    shown = shown[shown["metric"].isin(metric_rank)]
    keys = [
        (metric_rank[m], condition_rank.get(c, 99))
        for m, c in zip(shown["metric"], shown["condition"], strict=True)
    ]
    return shown.iloc[sorted(range(len(shown)), key=keys.__getitem__)]


def comparison_rows(report: StudyReport, group: str) -> list[Row]:
    """The comparison table of ``group``: each condition against the baseline per metric."""
    metrics, conditions = metrics_of(report, group), conditions_of(report)
    rows: list[Row] = []
    for r in _ordered(report.comparisons, group, metrics, conditions).to_dict("records"):
        _, factor = shown_metric_unit(str(r["metric"]), group)
        adjusted = float(r["p_adjusted"])
        rows.append(
            {
                "metric": metric_heading(str(r["metric"]), group),
                "condition": str(r["condition"]),
                "design": str(r["design"]),
                "n": f"{r['n_baseline']} / {r['n_condition']}",
                "left_out": number(r["left_out"]),
                "median_baseline": number(float(r["median_baseline"]) * factor),
                "median_condition": number(float(r["median_condition"]) * factor),
                "difference": number(float(r["median_difference"]) * factor, signed=True),
                "ci": _interval(float(r["ci_low"]) * factor, float(r["ci_high"]) * factor),
                "test": str(r["test"]),
                "p": p_text(float(r["p_value"])),
                "p_adjusted": p_text(adjusted),
                "significant": adjusted < SIGNIFICANCE,
                "effect": number(float(r["effect_size"]), 2, signed=True),
            }
        )
    return _spanned(rows)


def _interval(low: float, high: float) -> str:
    if math.isnan(low) or math.isnan(high):
        return MISSING
    return f"{number(low)} to {number(high)}"


def distribution_rows(report: StudyReport, group: str) -> list[Row]:
    """The distribution table of ``group``: subject values per metric and condition."""
    metrics, conditions = metrics_of(report, group), conditions_of(report)
    rows: list[Row] = []
    for r in _ordered(report.distributions, group, metrics, conditions).to_dict("records"):
        _, factor = shown_metric_unit(str(r["metric"]), group)
        scaled = {
            k: float(r[k]) * factor for k in ("median", "q1", "q3", "mean", "sd", "min", "max")
        }
        rows.append(
            {
                "metric": metric_heading(str(r["metric"]), group),
                "condition": str(r["condition"]),
                "subjects": number(r["subjects"]),
                "events": number(r["events"]),
                "median": number(scaled["median"]),
                "iqr": _interval(scaled["q1"], scaled["q3"]),
                "mean": number(scaled["mean"]),
                "sd": number(scaled["sd"]),
                "range": _interval(scaled["min"], scaled["max"]),
            }
        )
    return _spanned(rows)


def catalogue_rows(catalogue: pd.DataFrame) -> list[Row]:
    """Every session of the catalogue, formatted, excluded ones with their reason."""
    rows: list[Row] = []
    for r in catalogue.to_dict("records"):
        rows.append(
            {
                "session": str(r["session"]),
                "subject": str(r["subject"]),
                "condition": str(r["condition"]),
                "params": _params(r["params"]),
                "scenario": str(r["scenario"]),
                "body_region": _text(r["body_region"]),
                "start": _time(r["start_utc"]),
                "duration": number(r["duration_s"]),
                "collisions": number(r["collisions"]),
                "faults": number(r["faults"]),
                "dropped": number(r["dropped"]),
                "missed": number(r["missed_pct"], 2),
                "complete": bool(r["complete"]),
                "clean": bool(r["ended_cleanly"]),
                "flags": _flags(r["flags"]),
                "excluded": _text(r["excluded"]),
            }
        )
    return rows


def _records(frame: pd.DataFrame, columns: Iterable[str]) -> list[Row]:
    return [{c: number(r[c]) for c in columns} for r in frame.to_dict("records")]


def context(report: StudyReport, progress: Progress | None = None) -> dict[str, Any]:
    """Everything the template shows, as text (figures drawn here)."""
    numbered = 0
    groups = []
    for drawn in report_figures(report, progress):
        figures = []
        for figure in (*drawn.distributions, *drawn.curves):
            numbered += 1
            figures.append({"number": numbered, "title": figure.title, "svg": Markup(figure.svg)})
        curves = [c for c in report.curves if c.group == drawn.group]
        groups.append(
            {
                "id": f"group-{drawn.group}",
                "label": GROUP_LABELS.get(drawn.group, drawn.group),
                "comparisons": comparison_rows(report, drawn.group),
                "distributions": distribution_rows(report, drawn.group),
                "distribution_figures": figures[: len(drawn.distributions)],
                "curve_figures": figures[len(drawn.distributions) :],
                "curves": curves,
            }
        )
    excluded = sum(bool(_text(v)) for v in report.catalogue["excluded"])
    return {
        "report": report,
        "design": _records(report.design, report.design.columns),
        "design_columns": list(report.design.columns),
        "catalogue": catalogue_rows(report.catalogue),
        "excluded_sessions": excluded,
        "exclusions": _records(report.exclusions, ("target", "reason", "removed")),
        "groups": groups,
        "significance": f"{SIGNIFICANCE:g}",
    }


def environment() -> Environment:
    """The reports' templates (``templates/``): autoescaped, strict."""
    return Environment(
        loader=PackageLoader("hilrig.study", "templates"),
        autoescape=True,
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )


def render(report: StudyReport, *, progress: Progress | None = None) -> str:
    """The whole HTML document of ``report``; ``progress(title)`` after each figure drawn."""
    template = environment().get_template("report.html.j2")
    return template.render(context(report, progress))


def check_report_path(path: Path, *, overwrite: bool = False, flag: str = "--overwrite") -> None:
    """Refuse, before any work, a path :func:`write_report` could not write (OutputError;
    ``flag`` is the option that would allow replacing it)."""
    if path.exists() and not path.is_dir() and not overwrite:
        raise OutputError(f"{path}: already exists; pass {flag} to replace it")
    check_new_file(path, overwrite=overwrite)


def write_report(
    report: StudyReport,
    path: Path,
    *,
    overwrite: bool = False,
    progress: Progress | None = None,
) -> Path:
    """Write the HTML report of ``report`` to ``path``, whole or not at all; an existing file
    is replaced only with ``overwrite`` (OutputError otherwise, before anything is drawn)."""
    return write_html(path, lambda: render(report, progress=progress), overwrite=overwrite)


def write_html(
    path: Path, document: Callable[[], str], *, overwrite: bool = False, flag: str = "--overwrite"
) -> Path:
    """Write ``document()`` to ``path``, whole or not at all; an existing file is replaced only
    with ``overwrite`` (OutputError naming ``flag`` otherwise, before ``document`` is called)."""
    check_report_path(path, overwrite=overwrite, flag=flag)
    text = document()
    with new_files(path, overwrite=overwrite) as (temporary,):
        try:
            temporary.write_text(text, encoding="utf-8")
        except OSError as err:
            raise OutputError(f"{path}: cannot write ({err.strerror})") from err
    return path
