"""PNG figures equivalent to the paper's figures 4, 10-15 and 18-22 (matplotlib, Agg).

Figures are drawn on matplotlib ``Figure`` objects with an Agg canvas, never through pyplot, so
nothing opens a window or keeps global state. Each law has one colour in every figure.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from hilrig.control import Law
from hilrig.paper.experiments import (
    LAWS,
    OFFSET_DISPLAY,
    Experiment,
    ExperimentRun,
    PaperResults,
    SweepRun,
)

LAW_COLOURS = {Law.ADAPTIVE: "tab:red", Law.VARIABLE_STIFFNESS: "tab:blue", Law.FIXED: "tab:gray"}
INPUT_COLOUR = "black"
SWEEP_WINDOW_S = (0.0, 10.0)
_DPI = 120


@dataclass(frozen=True)
class FigureSet:
    """File names, units and time window of one section 3.4 experiment's figures."""

    inputs: str
    damping: str
    stiffness: str
    offsets: tuple[str, ...]  # one per reported axis
    input_label: str
    damping_unit: str
    stiffness_unit: str
    window_s: tuple[float, float]


FIGURES = {
    Experiment.END_EFFECTOR: FigureSet(
        "fig10-end-effector-force.png",
        "fig11-end-effector-damping.png",
        "fig12-end-effector-stiffness.png",
        ("fig13-offset-x.png", "fig14-offset-y.png", "fig15-offset-z.png"),
        input_label="force (N)",
        damping_unit="N·s/m",
        stiffness_unit="N/m",
        window_s=(3.0, 7.5),  # the paper's window for figures 13-15, used for 10-12 too
    ),
    Experiment.BODY: FigureSet(
        "fig18-joint-torque.png",
        "fig19-joint-damping.png",
        "fig20-joint-stiffness.png",
        ("fig21-offset-joint1.png", "fig22-offset-joint2.png"),
        input_label="torque (N·m)",
        damping_unit="N·m·s/rad",
        stiffness_unit="N·m/rad",
        window_s=(0.0, 10.0),  # the whole run
    ),
}
SWEEP_FIGURES = ("fig04a-mass-sweep.png", "fig04b-damping-sweep.png", "fig04c-stiffness-sweep.png")
_SWEEP_LABELS = {"m": ("m", "kg"), "b_d": ("b", "N·s/m"), "k_d": ("k", "N/m")}


def _figure(rows: int, title: str) -> tuple[Figure, list[Axes]]:
    figure = Figure(figsize=(7.5, 1.5 + 2.0 * rows), layout="constrained")
    FigureCanvasAgg(figure)
    axes = list(figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])
    figure.suptitle(title)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    return figure, axes


def _save(figure: Figure, path: Path) -> Path:
    figure.savefig(path, dpi=_DPI)
    return path


def _in_window(t_s: NDArray[np.float64], window_s: tuple[float, float]) -> NDArray[np.bool_]:
    return (t_s >= window_s[0]) & (t_s <= window_s[1])


def plot_inputs(run: ExperimentRun, path: Path) -> Path:
    """The collision inputs of the reported axes (figures 10 and 18)."""
    spec, figures = run.spec, FIGURES[run.spec.experiment]
    shown = _in_window(run.t_s, figures.window_s)
    figure, axes = _figure(len(spec.reported_axes), f"Collision input, {spec.experiment.label}")
    for ax, axis in zip(axes, spec.reported_axes, strict=True):
        column = spec.axes.index(axis)
        ax.plot(run.t_s[shown], run.inputs[shown, column], color=INPUT_COLOUR)
        ax.set_ylabel(f"{axis} {figures.input_label}")
    return _save(figure, path)


def _parameter(run: ExperimentRun, path: Path, *, damping: bool) -> Path:
    spec, figures = run.spec, FIGURES[run.spec.experiment]
    result = run.results[Law.ADAPTIVE]
    values = result.damping if damping else result.stiffness
    name, symbol = ("damping", "b") if damping else ("stiffness", "k")
    unit = figures.damping_unit if damping else figures.stiffness_unit
    title = f"Adaptive law {name} {symbol}_i(t), {spec.experiment.label}"
    if not damping:
        title += " (variable-stiffness law identical)"
    shown = _in_window(run.t_s, figures.window_s)
    figure, axes = _figure(len(spec.reported_axes), title)
    for ax, axis in zip(axes, spec.reported_axes, strict=True):
        column = spec.axes.index(axis)
        ax.plot(run.t_s[shown], values[shown, column], color=LAW_COLOURS[Law.ADAPTIVE])
        ax.set_ylabel(f"{symbol} {axis} ({unit})")
    return _save(figure, path)


def plot_damping(run: ExperimentRun, path: Path) -> Path:
    """b_i(t) of the adaptive law on every reported axis (figures 11 and 19)."""
    return _parameter(run, path, damping=True)


def plot_stiffness(run: ExperimentRun, path: Path) -> Path:
    """k_i(t) of the adaptive law on every reported axis (figures 12 and 20)."""
    return _parameter(run, path, damping=False)


def plot_offsets(run: ExperimentRun, axis: str, path: Path) -> Path:
    """The offset of one axis under the three laws (figures 13-15, 21 and 22)."""
    spec, figures = run.spec, FIGURES[run.spec.experiment]
    unit, scale = OFFSET_DISPLAY[spec.experiment]
    column = spec.axes.index(axis)
    t_s = run.offset_t_s
    shown = _in_window(t_s, figures.window_s)
    figure, (ax,) = _figure(1, f"Offset of {axis}, {spec.experiment.label}, three laws")
    for law in LAWS:
        offset = run.results[law].offset[shown, column] * scale
        ax.plot(t_s[shown], offset, color=LAW_COLOURS[law], label=law.value)
    ax.axvline(spec.onset_s, color=INPUT_COLOUR, linestyle=":", linewidth=1, label="onset")
    ax.set_ylabel(f"{axis} offset ({unit})")
    ax.legend()
    return _save(figure, path)


def plot_sweep(run: SweepRun, path: Path) -> Path:
    """Step responses of one section 2.1 sweep in mm (figure 4a, 4b or 4c)."""
    swept = run.sweep.parameter.value
    symbol, unit = _SWEEP_LABELS[swept]
    base = run.sweep.params(run.sweep.values[0])
    held = ", ".join(
        f"{s} = {base[name]:g} {u}" for name, (s, u) in _SWEEP_LABELS.items() if name != swept
    )
    title = f"Step response to f = {run.force_n:g} N with {held}; {symbol} varied"
    t_s = run.offset_t_s
    shown = _in_window(t_s, SWEEP_WINDOW_S)
    shades = colormaps["viridis"](np.linspace(0.0, 0.9, len(run.results)))
    figure, (ax,) = _figure(1, title)
    for value, result, colour in zip(run.sweep.values, run.results, shades, strict=True):
        label = f"{symbol} = {value:g} {unit}"
        ax.plot(t_s[shown], result.offset[shown, 0] * 1000.0, color=colour, label=label)
    ax.set_ylabel("offset (mm)")
    ax.legend()
    return _save(figure, path)


def figure_names() -> tuple[str, ...]:
    """Every figure's file name, in the order :func:`write_plots` lists them."""
    names = list(SWEEP_FIGURES)
    for figures in FIGURES.values():
        names += [figures.inputs, figures.damping, figures.stiffness, *figures.offsets]
    return tuple(names)


def _experiment_plots(run: ExperimentRun, paths: Mapping[str, Path]) -> None:
    figures = FIGURES[run.spec.experiment]
    drawers: list[tuple[str, Callable[[ExperimentRun, Path], Path]]] = [
        (figures.inputs, plot_inputs),
        (figures.damping, plot_damping),
        (figures.stiffness, plot_stiffness),
    ]
    for name, draw in drawers:
        draw(run, paths[name])
    for axis, name in zip(run.spec.reported_axes, figures.offsets, strict=True):
        plot_offsets(run, axis, paths[name])


def write_plots(results: PaperResults, paths: Mapping[str, Path]) -> None:
    """Write every figure as PNG, each to ``paths[<its name>]`` (names: :func:`figure_names`;
    the folders must exist)."""
    for sweep, name in zip(results.sweeps, SWEEP_FIGURES, strict=True):
        plot_sweep(sweep, paths[name])
    for run in results.runs:
        _experiment_plots(run, paths)
