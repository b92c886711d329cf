"""Force traces from CSV and Parquet tables, strictly validated.

A table has a time column ``t`` (s) and the force columns ``fx fy fz`` (N, the Cartesian
group) and/or ``tau1``..``tau6`` (N*m, the joint group); a group comes whole or not at all,
because its axes share one contact state. Other columns are ignored. Rows count from 0, the
first data row (for CSV the file line is given too).

Times are numbers in s, or timestamps (Parquet ``timestamp``, any unit or time zone) and
durations, which become s from the first row. Refused, with one line naming file, column and
row: a missing column; a column of another type (its type named: booleans, dates, forces as
timestamps..); a value that is not a number; a non-finite time; times that go backwards or
repeat; infinite force; missing force (NaN or an empty cell); fewer than two rows; a period
(the median step of all rows) of 1 s or more (times in ms, us or ns read as s); non-uniform
sampling, i.e. a step further than 1 % of the period from it. With ``resample``, rows with
missing force are dropped and the rest is interpolated linearly onto a uniform grid of that
period, from the first kept time to the last, unless one run's result over that grid would not
fit in this machine's memory; every other refusal stands. Times are kept as given (minus the
first) when the sampling is uniform; the period is the median step.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from hilrig.errors import ReplayError
from hilrig.replay.results import table_bytes
from hilrig.replay.trace import ForceTrace

TIME = "t"
FORCE_COLUMNS = {
    "cartesian": (("fx", "x"), ("fy", "y"), ("fz", "z")),
    "joint": tuple((f"tau{i}", f"joint{i}") for i in range(1, 7)),
}
#: Steps may differ from the median step by this fraction of it (clock quantisation, rounding).
UNIFORM_TOLERANCE = 0.01
#: Units per second of a timestamp or duration column (pandas holds s, ms, us or ns).
_PER_S = {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}
#: A period (median step) this long or longer is no admittance loop's: times not in s.
MAX_PERIOD_S = 1.0


def trace_from_table(path: Path, *, resample: bool = False) -> ForceTrace:
    """The trace of a ``.csv`` or ``.parquet`` table (see the module docstring).

    Raises ReplayError, one line naming file, column and row, for anything refused.
    """
    table = _Table(path)
    columns = table.columns
    if TIME not in columns:
        raise ReplayError(f"{path}: no time column {TIME!r} (has {', '.join(columns) or 'none'})")
    wanted: list[tuple[str, str]] = []
    for group in FORCE_COLUMNS.values():
        present = [c for c, _ in group if c in columns]
        if present and len(present) < len(group):
            missing = next(c for c, _ in group if c not in columns)
            raise ReplayError(
                f"{path}: no column {missing}: {', '.join(c for c, _ in group)} come together "
                f"(has {', '.join(present)})"
            )
        if present:
            wanted.extend(group)
    if not wanted:
        raise ReplayError(f"{path}: no force columns: fx, fy, fz and/or tau1..tau6 are needed")
    values = table.numbers([TIME, *(c for c, _ in wanted)])
    t = values[0]
    force = np.ascontiguousarray(values[1:].T)
    names = tuple(axis for _, axis in wanted)
    table.check_times(t)
    table.check_finite(force, [c for c, _ in wanted], allow_nan=resample)
    if len(t) < 2:
        raise ReplayError(f"{path}: {_rows(len(t))}; at least two are needed")
    dt_s = float(np.median(np.diff(t)))  # the period, from every row's time
    if dt_s >= MAX_PERIOD_S:
        raise ReplayError(
            f"{path}: column {TIME}: a period (median step) of {dt_s:g} s; an admittance loop "
            f"runs faster than {1 / MAX_PERIOD_S:g} Hz: are the times in s?"
        )
    notes: list[str] = []
    kept = np.isfinite(force).all(axis=1)
    if not kept.all():
        dropped = int((~kept).sum())
        notes.append(f"{path}: dropped {_rows(dropped)} with missing force")
        t, force = t[kept], force[kept]
        if len(t) < 2:
            raise ReplayError(f"{path}: {_rows(len(t))} with force; at least two are needed")
    steps = np.diff(t)
    deviation = np.abs(steps - dt_s)
    worst = int(np.argmax(deviation))
    if deviation[worst] > UNIFORM_TOLERANCE * dt_s:
        if not resample:
            row = int(np.flatnonzero(kept)[worst + 1])
            raise ReplayError(
                f"{table.where(TIME, row)}: non-uniform sampling: a step of {steps[worst]:.6g} s "
                f"where the median is {dt_s:.6g} s (largest deviation "
                f"{100 * deviation[worst] / dt_s:.3g} % of the period, more than "
                f"{100 * UNIFORM_TOLERANCE:g} %); pass --resample to interpolate onto a "
                f"uniform {dt_s:.6g} s grid"
            )
        _check_grid(path, t, dt_s, force.shape[1], float(steps.max()))
        t, force = _resampled(t, force, dt_s)
        notes.append(
            f"{path}: resampled onto a uniform {dt_s:.6g} s grid ({len(t)} ticks; largest gap "
            f"{float(steps.max()):.6g} s interpolated linearly)"
        )
    return ForceTrace(t - t[0], force, names, str(path), dt_s, notes=tuple(notes))


def _grid_ticks(t: NDArray[np.float64], dt_s: float) -> int:
    """Ticks of the uniform grid ``t[0] + n*dt_s`` up to ``t[-1]``."""
    return int(np.floor((t[-1] - t[0]) / dt_s + 1e-9)) + 1


def _check_grid(path: Path, t: NDArray[np.float64], dt_s: float, axes: int, gap_s: float) -> None:
    """Refuse a resampling grid over which one run's result would not fit in memory."""
    ticks = _grid_ticks(t, dt_s)
    need = table_bytes(axes, ticks)
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have:
        raise ReplayError(
            f"{path}: resampling onto a uniform {dt_s:.6g} s grid from {t[0]:.9g} to "
            f"{t[-1]:.9g} s makes {ticks} ticks (the largest gap is {gap_s:.6g} s): one run's "
            f"result would need {need / 2**30:.1f} GiB, more than this machine's "
            f"{have / 2**30:.1f} GiB"
        )


def _resampled(
    t: NDArray[np.float64], force: NDArray[np.float64], dt_s: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``force`` linearly interpolated at ``t[0] + n*dt_s`` up to ``t[-1]``."""
    count = _grid_ticks(t, dt_s)
    grid = t[0] + np.arange(count) * dt_s
    out = np.empty((count, force.shape[1]))
    for i in range(force.shape[1]):
        out[:, i] = np.interp(grid, t, force[:, i])
    return grid, out


class _Table:
    """One CSV or Parquet file: its column names, numeric columns and error locations."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.csv = path.suffix.lower() == ".csv"
        try:
            if self.csv:
                header = pd.read_csv(path, nrows=0)
                self.columns = [str(c) for c in header.columns]
            else:
                self.columns = list(pq.read_schema(path).names)
        except (OSError, ValueError, pd.errors.ParserError, pa.ArrowException) as err:
            kind = "CSV" if self.csv else "Parquet"
            raise ReplayError(f"{path}: cannot read as {kind}: {_first_line(err)}") from err

    def where(self, column: str, row: int) -> str:
        line = f" (line {row + 2})" if self.csv else ""
        return f"{self.path}: column {column}, row {row}{line}"

    def numbers(self, names: list[str]) -> NDArray[np.float64]:
        """The columns ``names`` as float64 rows (len(names), rows); the time column (the
        first) may hold timestamps or durations (s from its first row); refuses anything else.
        Parquet number columns go from Arrow to NumPy without a pandas frame between."""
        try:
            if self.csv:
                frame = pd.read_csv(self.path, usecols=names)
                columns: dict[str, pd.Series | pa.ChunkedArray] = {n: frame[n] for n in names}
            else:
                table = pq.read_table(self.path, columns=names)
                columns = {n: table.column(n) for n in names}
        except (OSError, ValueError, pd.errors.ParserError, pa.ArrowException) as err:
            raise ReplayError(f"{self.path}: cannot read: {_first_line(err)}") from err
        out = np.empty((len(names), len(next(iter(columns.values())))))
        for i, name in enumerate(names):
            found = columns[name]
            if isinstance(found, pa.ChunkedArray):
                if pa.types.is_floating(found.type) or pa.types.is_integer(found.type):
                    out[i] = found.cast(pa.float64(), safe=False).to_numpy()  # null -> NaN
                    continue
                found = found.to_pandas()
            column = found
            kind = column.dtype.kind
            if kind in "fiu":
                out[i] = column.to_numpy(dtype=np.float64, na_value=np.nan)
            elif kind in "Mm" and name == TIME:
                out[i] = _seconds(column)
            elif kind == "O" or isinstance(column.dtype, pd.CategoricalDtype | pd.StringDtype):
                out[i] = self._coerced(name, column)
            else:
                what = (
                    "times must be numbers (s) or timestamps"
                    if name == TIME
                    else ("forces must be numbers (N or N*m)")
                )
                raise ReplayError(f"{self.path}: column {name} has type {column.dtype}; {what}")
        return out

    def _coerced(self, name: str, column: pd.Series) -> NDArray[np.float64]:
        """Values that are not typed as numbers (CSV text, strings, decimals) as float64."""
        coerced = pd.to_numeric(column, errors="coerce")
        bad = (coerced.isna() & column.notna()).to_numpy()
        if bad.any():
            row = int(np.argmax(bad))
            raise ReplayError(f"{self.where(name, row)}: {column.iloc[row]!r} is not a number")
        numbers: NDArray[np.float64] = coerced.to_numpy(dtype=np.float64, na_value=np.nan)
        return numbers

    def check_times(self, t: NDArray[np.float64]) -> None:
        """Finite and strictly increasing, else the first offending row."""
        bad = ~np.isfinite(t)
        if bad.any():
            row = int(np.argmax(bad))
            what = "missing" if np.isnan(t[row]) else t[row]
            raise ReplayError(f"{self.where(TIME, row)}: time is {what}")
        steps = np.diff(t)
        back = steps <= 0
        if back.any():
            row = int(np.argmax(back)) + 1
            what = (
                f"time {t[row]:.9g} s repeats row {row - 1}"
                if steps[row - 1] == 0
                else f"time {t[row]:.9g} s is before row {row - 1}'s {t[row - 1]:.9g} s"
            )
            raise ReplayError(f"{self.where(TIME, row)}: {what}; times must increase")

    def check_finite(
        self, force: NDArray[np.float64], names: list[str], *, allow_nan: bool
    ) -> None:
        """No infinite force; no missing force unless ``allow_nan`` (rows dropped later)."""
        bad = np.isinf(force) if allow_nan else ~np.isfinite(force)
        if bad.any():
            row, i = np.unravel_index(int(np.argmax(bad)), force.shape)
            value = force[row, i]
            why = (
                "missing (NaN or empty); pass --resample to drop such rows and interpolate"
                if np.isnan(value)
                else f"{value}: infinite force is refused"
            )
            raise ReplayError(f"{self.where(names[int(i)], int(row))}: {why}")


def _seconds(column: pd.Series) -> NDArray[np.float64]:
    """Timestamps (any unit or time zone) or durations as s from the first row; NaT is NaN."""
    if isinstance(column.dtype, pd.DatetimeTZDtype):
        column = column.dt.tz_convert("UTC").dt.tz_localize(None)
    values = column.to_numpy()
    unit, count = np.datetime_data(values.dtype)
    ticks = values.view(np.int64)  # in the column's own unit: no conversion can overflow
    seconds = (ticks - ticks[:1]).astype(np.float64)
    seconds /= _PER_S[unit] / count  # correctly rounded: 1000 us is 0.001 s exactly
    seconds[column.isna().to_numpy()] = np.nan
    return seconds


def _rows(count: int) -> str:
    return f"{count} row{'s' * (count != 1)}"


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__
