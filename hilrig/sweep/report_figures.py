"""A sweep report's figures: each metric against the swept parameter, one figure per axis group.

The x axis is the one numeric setting that varies across the runs (with two or more, the one
with the most values; the others name the lines with the controller). Each line is the median
over subjects of each subject's mean (the summary's value), with the band between the subjects'
quartiles; a run without that setting (another controller, say) is a dashed level line across
the figure. Without a numeric setting that varies, each run is a point with its quartiles.
Figures are inline SVG drawn by :mod:`hilrig.study.figures`'s canvas.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib as mpl
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import FixedFormatter, FixedLocator, NullLocator

from hilrig.replay.specs import ControllerSpec, Value
from hilrig.study.figures import GROUP_LABELS, PALETTE, RC, SvgFigure, finish, new_figure
from hilrig.study.records import METRIC_LABELS, STUDY_METRICS, shown_metric_unit

OVER = "over_pct"  # the share of judged events over an ISO/TS 15066 limit, in the figures
LABELS = METRIC_LABELS | {OVER: "events over a limit"}
LEGEND_MAX = 8  # lines named in a legend; more are drawn unnamed
DECADE = 10.0  # the span of x values from which the axis is logarithmic
MAX_TICKS = 8  # x ticks at every value swept up to this many
MAX_NAMED_RUNS = 20  # runs side by side named under the x axis up to this many


@dataclass(frozen=True)
class Layout:
    """Where each run goes: ``x`` the swept setting's key (None: runs side by side), ``xs``
    each run's value of it (None: a level line), ``lines`` each run's line name; ``log_x``
    when the values are positive and span a decade or more (a log axis spaces 2, 5, 10, 20,
    40 evenly)."""

    x: str | None
    xs: dict[str, float | None]
    lines: dict[str, str]
    log_x: bool = False


def _number(value: Value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def layout(specs: Sequence[ControllerSpec]) -> Layout:
    """The x axis and the lines of the runs ``specs``, as the module docstring says."""
    settings = {s.name: {x.key: x.value for x in s.settings} for s in specs}
    values: dict[str, set[float]] = {}
    numeric: dict[str, bool] = {}
    for run in settings.values():
        for key, value in run.items():
            number = _number(value)
            numeric[key] = numeric.get(key, True) and number is not None
            values.setdefault(key, set()).add(number or 0.0)
    swept = [k for k in values if numeric[k] and len(values[k]) > 1]
    if not swept:
        return Layout(None, dict.fromkeys(settings), {s.name: s.name for s in specs})
    x = max(swept, key=lambda k: (len(values[k]), -list(values).index(k)))
    xs = {name: _number(run[x]) if x in run else None for name, run in settings.items()}
    lines = {}
    for spec in specs:
        rest = [s.label for s in spec.settings if s.key != x]
        named = " ".join([spec.controller, *rest])
        lines[spec.name] = named if x in settings[spec.name] else spec.name
    low, high = min(values[x]), max(values[x])
    return Layout(x, xs, lines, log_x=low > 0 and high >= DECADE * low)


def _log_ticks(values: list[float]) -> list[float]:
    """The values swept, or with more than :data:`MAX_TICKS` of them 1, 2 and 5 of each decade
    between the first and the last."""
    if len(values) <= MAX_TICKS:
        return values
    first, last = values[0], values[-1]
    decades = range(math.floor(math.log10(first)), math.ceil(math.log10(last)) + 1)
    steps = (m * 10.0**e for e in decades for m in (1, 2, 5))
    return [x for x in steps if first <= x <= last]


def with_over(by_run: pd.DataFrame) -> pd.DataFrame:
    """``by_run`` with :data:`OVER`: the percentage of judged events over a limit."""
    judged = by_run["judged"].to_numpy(dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(judged > 0, 100.0 * by_run["over"].to_numpy(dtype=float) / judged, np.nan)
    return by_run.assign(**{OVER: share})


def quartiles(by_subject: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Per run (in order of appearance) the subjects' first and third quartile of ``metric``
    (NaN subjects left out, as in the median)."""
    grouped = by_subject.groupby("run", sort=False)[metric]
    return pd.DataFrame({"q1": grouped.quantile(0.25), "q3": grouped.quantile(0.75)})


def sweep_figure(
    group: str, by_run: pd.DataFrame, by_subject: pd.DataFrame, where: Layout
) -> SvgFigure:
    """The figure of one axis group: a panel per metric with a value, then the share over."""
    with mpl.rc_context(RC):
        figure = draw(group, by_run, by_subject, where)
        title = f"{GROUP_LABELS.get(group, group)}: each metric across the runs"
        figure.suptitle(title)
        return finish(figure, f"sweep-{group}", title)


def draw(group: str, by_run: pd.DataFrame, by_subject: pd.DataFrame, where: Layout) -> Figure:
    """:func:`sweep_figure`'s panels, drawn (call inside ``mpl.rc_context(RC)``)."""
    metrics = [m for m in (*STUDY_METRICS, OVER) if by_run[m].notna().any()]
    columns = 3
    rows = -(-len(metrics) // columns)
    figure = new_figure(10.5, 2.6 * rows + 0.5)
    panels = figure.subplots(rows, columns, squeeze=False).ravel()
    names = list(dict.fromkeys(where.lines[r] for r in by_run["run"]))
    colours = {name: PALETTE[i % len(PALETTE)] for i, name in enumerate(names)}
    for axes, metric in zip(panels, metrics, strict=False):
        _panel(axes, metric, group, by_run, by_subject, where, colours)
    for axes in panels[len(metrics) :]:
        axes.set_visible(False)
    if len(names) <= LEGEND_MAX:
        handles, labels = panels[0].get_legend_handles_labels()
        figure.legend(handles, labels, loc="outside lower center", ncols=min(len(names), 4))
    return figure


def _panel(
    axes: Axes,
    metric: str,
    group: str,
    by_run: pd.DataFrame,
    by_subject: pd.DataFrame,
    where: Layout,
    colours: dict[str, str],
) -> None:
    unit, factor = ("%", 1.0) if metric == OVER else shown_metric_unit(metric, group)
    spread = None if metric == OVER else quartiles(by_subject, metric) * factor
    medians = by_run.set_index("run")[metric] * factor
    runs = list(by_run["run"])
    if where.x is None:
        for i, run in enumerate(runs):
            low, high = (np.nan, np.nan) if spread is None else spread.loc[run]
            axes.errorbar(
                i,
                medians[run],
                yerr=[[medians[run] - low], [high - medians[run]]],
                fmt="o",
                color=colours[where.lines[run]],
                label=where.lines[run],
            )
        if len(runs) <= MAX_NAMED_RUNS:
            axes.set_xticks(range(len(runs)), runs, rotation=30, ha="right")
        else:  # names would overlap: the table below the figure names them in this order
            axes.set_xlabel("run, in the table's order")
    else:
        for name in dict.fromkeys(where.lines[r] for r in runs):
            mine = [r for r in runs if where.lines[r] == name]
            colour = colours[name]
            level = [r for r in mine if where.xs[r] is None]
            if level:
                axes.axhline(medians[level[0]], color=colour, linestyle="--", label=name)
                if spread is not None:
                    low, high = spread.loc[level[0]]
                    axes.axhspan(low, high, color=colour, alpha=0.1, lw=0)
                continue
            mine.sort(key=lambda r: where.xs[r] or 0.0)
            xs = [where.xs[r] or 0.0 for r in mine]  # every one has a value here
            axes.plot(xs, medians[mine], marker="o", markersize=3, color=colour, label=name)
            if spread is not None:
                band = spread.loc[mine]
                axes.fill_between(xs, band["q1"], band["q3"], color=colour, alpha=0.15, lw=0)
        axes.set_xlabel(where.x)
        if where.log_x:  # ticks at the values swept, as plain numbers (no mathtext here: RC)
            axes.set_xscale("log")
            ticks = _log_ticks(sorted({x for x in where.xs.values() if x is not None}))
            axes.xaxis.set_major_locator(FixedLocator(ticks))
            axes.xaxis.set_major_formatter(FixedFormatter([f"{x:g}" for x in ticks]))
            axes.xaxis.set_minor_locator(NullLocator())
    axes.set_title(f"{LABELS[metric]} ({unit})")
