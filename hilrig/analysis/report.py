"""Analysis results for people (rich tables) and for programs (CSV and Parquet files).

Tables show offsets in mm on Cartesian axes (rad on joints), the way the paper reports them;
files keep SI units, with the unit of every value in a ``unit`` column.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from rich import box
from rich.table import Table

from hilrig.analysis.compare import Analysis
from hilrig.analysis.metrics import unit
from hilrig.analysis.verdict import Verdict
from hilrig.errors import AnalysisError
from hilrig.outputs import check_new_file, new_files

LABELS = {
    "peak_force": "peak force",
    "max_abs_offset": "max |offset|",
    "time_to_max_offset_s": "response time",
    "recovery_time_s": "recovery time",
    "peak_offset_rate": "peak offset rate",
    "peak_commanded_joint_speed_rad_s": "peak joint speed",
    "tracking_rms": "tracking RMS",
}
SHOWN_AS = {"m": ("mm", 1000.0), "m/s": ("mm/s", 1000.0)}  # SI unit -> (display unit, factor)
FILE_SUFFIXES = (".csv", ".parquet")
#: Schema metadata key of a replay result table (hilrig.replay's contract).
REPLAY_RUNS_KEY = b"hilrig.runs"


def shown_unit(si_unit: str) -> tuple[str, float]:
    """The unit a value in ``si_unit`` is shown in and the factor to it (``*`` as ``·``)."""
    shown, factor = SHOWN_AS.get(si_unit, (si_unit, 1.0))
    return shown.replace("*", "·"), factor


def shown(value: float, si_unit: str) -> str:
    """``value`` (in ``si_unit``) in its shown unit, 4 significant digits; NaN as "-"."""
    if math.isnan(value):
        return "-"
    _, factor = shown_unit(si_unit)
    return f"{value * factor:.4g}"


def events_table(analysis: Analysis) -> Table:
    """The collision events of one source: group, start, end, duration (s) and peak."""
    table = Table(title="collision events", title_justify="left")
    for column in ("#", "group", "start s", "end s", "duration s", "peak"):
        table.add_column(column, justify="left" if column == "group" else "right")
    for number, event in enumerate(analysis.events):
        peak = f"{event.peak:.3g} {unit('peak_force', event.group)}"
        table.add_row(
            str(number),
            event.group.value,
            f"{event.start_s:.3f}",
            f"{event.end_s:.3f}",
            f"{event.duration_s:.3f}",
            peak,
        )
    return table


def verdicts_table(analysis: Analysis) -> Table:
    """Each run's safety verdict per Cartesian collision (ISO/TS 15066; docs/safety.md)."""
    table = Table(title=f"safety against ISO/TS 15066: {analysis.judged}", title_justify="left")
    heads = ("#", "run", "peak N", "transient N", "limit N", "after N", "limit N", "N/cm^2",
             "energy J", "robot kg", "speed m/s", "limit m/s", "verdict", "margin")  # fmt: skip
    for head in heads:
        table.add_column(head, justify="left" if head in ("run", "verdict") else "right")
    for v in analysis.verdicts:
        verdict = "[green]within[/]" if v.verdict == "within" else "[red]OVER[/]"
        table.add_row(
            str(v.event),
            v.run,
            *(
                _number(x)
                for x in (
                    v.peak_force_n,
                    v.transient_peak_n,
                    v.transient_limit_n,
                    v.quasi_static_peak_n,
                    v.quasi_static_limit_n,
                    v.pressure_n_cm2,
                    v.energy_j,
                    v.effective_mass_kg,
                    v.approach_speed_m_s,
                    v.speed_limit_m_s,
                )
            ),
            verdict,
            f"{v.margin_pct:+.1f} % ({v.binding})",
        )
    return table


def verdict_line(analysis: Analysis) -> str:
    """One line: how many collisions are within the limits, and the smallest margin."""
    if not analysis.region:
        return f"safety: {analysis.judged}"
    if not analysis.verdicts:
        return f"safety ({analysis.judged}): no Cartesian collision to judge"
    over = sum(v.verdict == "over" for v in analysis.verdicts)
    worst = min(analysis.verdicts, key=lambda v: v.margin_pct)
    return (
        f"safety ({analysis.judged}): {len(analysis.verdicts) - over} within, {over} over; "
        f"smallest margin {worst.margin_pct:+.1f} % ({worst.binding}, event {worst.event}, "
        f"run {worst.run})"
    )


def _figures(v: Verdict) -> tuple[float, ...]:
    return (v.peak_force_n, v.transient_peak_n, v.transient_limit_n, v.quasi_static_peak_n,
            v.quasi_static_limit_n, v.pressure_n_cm2, v.energy_j, v.effective_mass_kg,
            v.approach_speed_m_s, v.speed_limit_m_s)  # fmt: skip


def _number(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.3g}"


def comparison_table(comparison: pd.DataFrame, *, baseline: str, title: str) -> Table:
    """A :func:`~hilrig.analysis.compare.comparison` in the paper's style: one row per key
    (event and axis, or axis) and metric, one column per run, each cell the value and its
    change against ``baseline`` in %; ``n`` values averaged are shown when more than one.
    A metric with no value in any run (joint speeds where none were recorded) is left out."""
    keys = [k for k in ("event", "axis") if k in comparison.columns]
    runs = [str(r) for r in dict.fromkeys(comparison["run"])]
    table = Table(title=f"{title} (change vs {baseline})", title_justify="left", box=box.SIMPLE)
    for name in keys:
        table.add_column(name)
    table.add_column("metric")
    for run in runs:
        table.add_column(run, justify="right")
    averaged = bool((comparison["n"] > 1).any())
    rows: dict[tuple[str, ...], dict[str, str]] = {}
    for record in comparison.to_dict("records"):
        si_unit = str(record["unit"])
        metric = str(record["metric"])
        label = f"{LABELS.get(metric, metric)} {SHOWN_AS.get(si_unit, (si_unit,))[0]}"
        key = (*("all" if pd.isna(record[k]) else str(record[k]) for k in keys), label)
        cell = shown(float(record["value"]), si_unit)
        change = float(record["change_pct"])
        if record["run"] != baseline and not math.isnan(change):
            cell += f" ({change:+.1f} %)"
        if averaged:
            cell += f" n={record['n']}"
        rows.setdefault(key, dict.fromkeys(runs, ""))[str(record["run"])] = cell
    for key, cells in rows.items():
        if any(cell not in ("", "-") for cell in cells.values()):  # no value in any run: omitted
            table.add_row(*key, *cells.values())
    return table


def check_table_path(path: Path, *, overwrite: bool = False) -> None:
    """Refuse, before any work, a comparison file :func:`write_table` could not write: another
    suffix, a file already there unless ``overwrite``, a replay result even then
    (AnalysisError); a missing or read-only folder (OutputError)."""
    if path.suffix not in FILE_SUFFIXES:
        raise AnalysisError(f"{path}: write a .csv or a .parquet file (or a folder for a dataset)")
    if path.exists() and not overwrite:
        raise AnalysisError(f"{path}: already exists; pass --overwrite to replace it")
    if path.suffix == ".parquet" and path.is_file():
        try:
            metadata = pq.read_schema(path).metadata or {}
        except (OSError, pa.ArrowException):
            metadata = {}  # not Parquet: whatever it is, --overwrite was asked for
        if REPLAY_RUNS_KEY in metadata:
            raise AnalysisError(
                f"{path}: is a replay result; refusing to replace it, even with --overwrite"
            )
    check_new_file(path, overwrite=overwrite)


def write_table(frames: Sequence[pd.DataFrame], path: Path, *, overwrite: bool = False) -> Path:
    """Concatenate ``frames`` and write them to ``path`` (.csv or .parquet, by its suffix),
    whole or not at all (:func:`hilrig.outputs.new_files`); an existing file is replaced only
    with ``overwrite``.

    Raises AnalysisError (OutputError for the folder) if ``path`` cannot be written.
    """
    check_table_path(path, overwrite=overwrite)
    frame = pd.concat(frames, ignore_index=True)
    with new_files(path, overwrite=overwrite) as (temporary,):
        try:
            if path.suffix == ".csv":
                frame.to_csv(temporary, index=False)
            else:
                frame.to_parquet(temporary, index=False)
        except OSError as err:
            raise AnalysisError(f"{path}: cannot write ({err})") from err
    return path
