"""The figures of a study report as inline SVG text (matplotlib, Agg canvas, no pyplot).

Text is drawn as paths (``svg.fonttype`` "path"), so a figure needs no font; the XML prolog,
metadata and comments are dropped and every ``id`` is prefixed with the figure's key, so many
figures sit in one HTML document. Each ``<svg>`` carries ``role="img"``, an ``aria-label`` and a
``<title>``. Each condition has one colour in every figure of a report.
"""

from __future__ import annotations

import html
import io
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from hilrig.study.records import (
    METRIC_LABELS,
    STUDY_METRICS,
    EventCurve,
    StudyReport,
    shown_metric_unit,
)

GROUP_ORDER = ("cartesian", "joint")
GROUP_LABELS = {"cartesian": "Cartesian axes (x, y, z)", "joint": "joints"}
PALETTE = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2")
_BASELINE_COLOUR = "#555555"
RC: dict[Any, Any] = {  # matplotlib types its keys as literals
    "svg.fonttype": "path",
    "svg.hashsalt": "hilrig-study",  # the same report twice is the same text
    "text.parse_math": False,  # a "$" in a condition's name is a dollar sign
    "font.size": 8.0,
    "axes.titlesize": 9.0,
    "axes.labelsize": 8.0,
    "legend.fontsize": 7.5,
    "axes.spines.top": False,
    "axes.spines.right": False,
}
_PARAMETER_UNITS = {
    "cartesian": ("N·s/m", "N/m"),
    "joint": ("N·m·s/rad", "N·m/rad"),
}


@dataclass(frozen=True)
class SvgFigure:
    """One drawn figure: ``key`` (unique in a report, prefixes its ids), title, SVG text."""

    key: str
    title: str
    svg: str


def conditions_of(report: StudyReport) -> list[str]:
    """Every condition of ``report``: the baseline first, then in the design's order."""
    found = [*report.design.get("condition", []), *report.subject_values.get("condition", [])]
    found += [c.condition for c in report.curves]
    rest = [str(c) for c in dict.fromkeys(found) if str(c) != report.baseline]
    return [report.baseline, *rest]


def condition_colours(conditions: Sequence[str], baseline: str) -> dict[str, str]:
    """One colour per condition: the baseline grey, the others from a fixed palette."""
    others = [c for c in conditions if c != baseline]
    colours = {c: PALETTE[i % len(PALETTE)] for i, c in enumerate(others)}
    return {baseline: _BASELINE_COLOUR, **colours}


def groups_of(report: StudyReport) -> list[str]:
    """The groups with subject values or curves, Cartesian first."""
    found = {str(g) for g in report.subject_values.get("group", [])}
    found |= {c.group for c in report.curves}
    return sorted(found, key=lambda g: (GROUP_ORDER.index(g) if g in GROUP_ORDER else 9, g))


def metrics_of(report: StudyReport, group: str) -> list[str]:
    """The metrics of ``group`` with at least one subject value, in display order."""
    values = report.subject_values
    shown = values[(values["group"] == group) & values["value"].notna()]
    present = set(shown["metric"])
    return [m for m in STUDY_METRICS if m in present]


def figure_count(report: StudyReport) -> int:
    """How many figures :func:`report_figures` draws (for a progress bar)."""
    count = 0
    for group in groups_of(report):
        count += len(metrics_of(report, group))
        count += 2 if any(c.group == group for c in report.curves) else 0
    return count


def new_figure(width_in: float, height_in: float) -> Figure:
    """An empty figure on an Agg canvas (no pyplot, no global state), constrained layout."""
    figure = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


_ID = re.compile(r'\sid="([^"]+)"')
_REFERENCE = re.compile(r'(href="#|url\(#)([^")]+)')


def _svg_text(figure: Figure, key: str, title: str) -> str:
    """``figure`` as SVG to embed in HTML: no prolog, metadata, comments or namespace
    declarations (HTML needs none; links are SVG 2 ``href``), ids prefixed with ``key``."""
    buffer = io.StringIO()
    metadata = {"Title": title, "Creator": None, "Date": None, "Format": None, "Type": None}
    figure.savefig(buffer, format="svg", metadata=metadata)
    text = buffer.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(r"\s*<metadata>.*?</metadata>", "", text, flags=re.DOTALL)
    text = re.sub(r"\s*<!--.*?-->", "", text, flags=re.DOTALL)
    referenced = {m.group(2) for m in _REFERENCE.finditer(text)}
    text = _ID.sub(lambda m: f' id="{key}-{m[1]}"' if m[1] in referenced else "", text)
    text = _REFERENCE.sub(lambda m: f"{m[1]}{key}-{m[2]}", text)
    text = re.sub(r'\s+xmlns(:xlink)?="[^"]*"', "", text).replace("xlink:href=", "href=")
    label = html.escape(title, quote=True)
    return text.replace("<svg ", f'<svg class="figure" role="img" aria-label="{label}" ', 1)


def finish(figure: Figure, key: str, title: str) -> SvgFigure:
    """``figure`` drawn as an :class:`SvgFigure` to embed (ids prefixed with ``key``)."""
    return SvgFigure(key, title, _svg_text(figure, key, title))


def _capital(text: str) -> str:
    return text[:1].upper() + text[1:]


def _tick_label(name: str, width: int = 12) -> str:
    """``name`` on up to two lines of about ``width`` characters (split after "_", " ", "-" or
    "," or before "(", nearest the middle), each cut with an ellipsis if still longer."""
    if len(name) > width:
        cuts = [i + 1 for i, c in enumerate(name[:-1]) if c in "_ -,"]
        cuts += [i for i, c in enumerate(name) if c == "(" and i > 0]
        if cuts:
            cut = min(cuts, key=lambda i: abs(i - len(name) / 2))
            return "\n".join(_cut(part.strip(), width + 2) for part in (name[:cut], name[cut:]))
    return _cut(name, width + 2)


def _cut(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 1] + "\u2026"


def distribution_figure(
    report: StudyReport, group: str, metric: str, colours: dict[str, str]
) -> SvgFigure:
    """Every subject's value of ``metric`` per condition: a box per condition, each subject a
    jittered point, a subject's points across conditions joined by a thin line."""
    values = report.subject_values
    rows = values[(values["group"] == group) & (values["metric"] == metric)]
    rows = rows[rows["value"].notna()]
    conditions = [c for c in conditions_of(report) if c in set(rows["condition"])]
    unit, factor = shown_metric_unit(metric, group)
    label = METRIC_LABELS.get(metric, metric)
    title = f"{_capital(label)}, {GROUP_LABELS.get(group, group)}: subject values per condition"
    with mpl.rc_context(RC):
        figure = new_figure(3.3, 2.7)
        ax = figure.subplots()
        rng = np.random.default_rng(0)
        points: dict[str, dict[int, tuple[float, float]]] = {}
        for position, condition in enumerate(conditions):
            sample = rows[rows["condition"] == condition].sort_values("subject")
            y = sample["value"].to_numpy(dtype=float) * factor
            colour = colours.get(condition, _BASELINE_COLOUR)
            ax.boxplot(
                [y], positions=[position], widths=0.5, showfliers=False, patch_artist=True,
                boxprops={"facecolor": colour, "alpha": 0.22, "edgecolor": colour},
                medianprops={"color": colour, "linewidth": 1.6},
                whiskerprops={"color": colour}, capprops={"color": colour},
            )  # fmt: skip
            x = position + rng.uniform(-0.14, 0.14, size=len(y))
            ax.scatter(x, y, s=14, color=colour, edgecolors="white", linewidths=0.5, zorder=3)
            for subject, xi, yi in zip(sample["subject"], x, y, strict=True):
                points.setdefault(str(subject), {})[position] = (float(xi), float(yi))
        for seen in points.values():
            if len(seen) > 1:
                xs, ys = zip(*(seen[p] for p in sorted(seen)), strict=True)
                ax.plot(xs, ys, color="0.55", linewidth=0.6, alpha=0.6, zorder=2)
        counts = rows.groupby("condition")["subject"].nunique()
        names = [_tick_label(c).split("\n") for c in conditions]
        lines = max((len(n) for n in names), default=1)
        ticks = [
            "\n".join([*n, *[""] * (lines - len(n)), f"n={counts.get(c, 0)}"])
            for n, c in zip(names, conditions, strict=True)
        ]
        ax.set_xticks(range(len(conditions)), ticks)
        ax.set_xlim(-0.6, len(conditions) - 0.4)
        ax.set_ylabel(f"{label} ({unit})")
        ax.set_title(_capital(label))
        ax.grid(True, axis="y", alpha=0.3)
        return finish(figure, f"dist-{group}-{metric}", title)


def _curve_label(curve: EventCurve) -> str:
    return f"{curve.condition} ({curve.subject}, {curve.axis})"


def _time_axes(figure: Figure, rows: int) -> list[Axes]:
    axes = list(figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.axvline(0.0, color="0.3", linestyle=":", linewidth=0.8)
    axes[-1].set_xlabel("time from the event's start (s)")
    return axes


def _legend(figure: Figure, axes: list[Axes]) -> None:
    handles, labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 3))


def response_figure(curves: Sequence[EventCurve], group: str, colours: dict[str, str]) -> SvgFigure:
    """Force and offset over time of one representative event per condition of ``group``."""
    force_unit, _ = shown_metric_unit("peak_force", group)
    offset_unit, factor = shown_metric_unit("max_abs_offset", group)
    noun = "torque" if group == "joint" else "force"
    title = f"Representative events, {GROUP_LABELS.get(group, group)}: {noun} and offset"
    with mpl.rc_context(RC):
        figure = new_figure(5.6, 4.0)
        force_ax, offset_ax = _time_axes(figure, 2)
        for curve in curves:
            colour = colours.get(curve.condition, _BASELINE_COLOUR)
            force_ax.plot(curve.t_s, curve.force, color=colour, lw=1.0, label=_curve_label(curve))
            offset_ax.plot(curve.t_s, curve.offset * factor, color=colour, lw=1.0)
        force_ax.set_ylabel(f"{noun} ({force_unit})")
        offset_ax.set_ylabel(f"offset ({offset_unit})")
        figure.suptitle(title, fontsize=9)
        _legend(figure, [force_ax])
        return finish(figure, f"response-{group}", title)


def parameters_figure(
    curves: Sequence[EventCurve], group: str, colours: dict[str, str]
) -> SvgFigure:
    """Damping b, stiffness k and damping ratio zeta over time during one representative event
    per condition of ``group``."""
    damping_unit, stiffness_unit = _PARAMETER_UNITS.get(group, ("SI", "SI"))
    title = f"Representative events, {GROUP_LABELS.get(group, group)}: controller parameters"
    with mpl.rc_context(RC):
        figure = new_figure(5.6, 5.0)
        axes = _time_axes(figure, 3)
        for curve in curves:
            colour = colours.get(curve.condition, _BASELINE_COLOUR)
            series = (curve.damping, curve.stiffness, curve.zeta)
            for index, (ax, values) in enumerate(zip(axes, series, strict=True)):
                label = _curve_label(curve) if index == 0 else None
                ax.plot(curve.t_s, values, color=colour, lw=1.0, label=label)
        axes[0].set_ylabel(f"damping b ({damping_unit})")
        axes[1].set_ylabel(f"stiffness k ({stiffness_unit})")
        axes[2].set_ylabel("damping ratio ζ")
        figure.suptitle(title, fontsize=9)
        _legend(figure, axes)
        return finish(figure, f"parameters-{group}", title)


@dataclass(frozen=True)
class GroupFigures:
    """The figures of one group: a distribution per metric, then the event curves (if any)."""

    group: str
    distributions: tuple[SvgFigure, ...]
    curves: tuple[SvgFigure, ...]


def report_figures(
    report: StudyReport, progress: Callable[[str], None] | None = None
) -> list[GroupFigures]:
    """Every figure of ``report``, per group; ``progress(title)`` after each one drawn."""
    colours = condition_colours(conditions_of(report), report.baseline)
    drawn: list[GroupFigures] = []

    def done(figure: SvgFigure) -> SvgFigure:
        if progress is not None:
            progress(figure.title)
        return figure

    for group in groups_of(report):
        distributions = tuple(
            done(distribution_figure(report, group, metric, colours))
            for metric in metrics_of(report, group)
        )
        curves = [c for c in report.curves if c.group == group]
        order = {c: i for i, c in enumerate(conditions_of(report))}
        curves.sort(key=lambda c: order.get(c.condition, len(order)))
        shown: tuple[SvgFigure, ...] = ()
        if curves:
            shown = (
                done(response_figure(curves, group, colours)),
                done(parameters_figure(curves, group, colours)),
            )
        drawn.append(GroupFigures(group, distributions, shown))
    return drawn
