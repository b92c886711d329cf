"""CSV and Parquet inputs: what is read, and every malformed table with its one-line error."""

from __future__ import annotations

import datetime
import io
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hilrig.replay import ReplayError, load_trace, tables
from hilrig.replay.tables import UNIFORM_TOLERANCE

FORMATS = ("csv", "parquet")


def table(tmp_path: Path, fmt: str, text: str) -> Path:
    """``text`` (CSV) as a .csv file, or as a .parquet file with the types pandas infers."""
    path = tmp_path / f"input.{fmt}"
    if fmt == "csv":
        path.write_text(text)
    else:
        pd.read_csv(io.StringIO(text)).to_parquet(path)
    return path


def where(path: Path, column: str, row: int) -> str:
    line = f" (line {row + 2})" if path.suffix == ".csv" else ""
    return f"{path}: column {column}, row {row}{line}"


def refused(path: Path, *, resample: bool = False) -> str:
    with pytest.raises(ReplayError) as caught:
        load_trace(path, resample=resample)
    message = str(caught.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize("fmt", FORMATS)
def test_both_groups_are_read_exactly_in_axis_order(tmp_path: Path, fmt: str) -> None:
    rng = np.random.default_rng(3)
    values = rng.normal(size=(50, 9))
    frame = pd.DataFrame(values, columns=["fx", "fy", "fz", *(f"tau{i}" for i in range(1, 7))])
    frame.insert(0, "note", "x")  # other columns are ignored
    frame.insert(0, "t", 10.0 + np.arange(50) * 0.001)
    path = tmp_path / f"both.{fmt}"
    if fmt == "csv":
        frame.to_csv(path, index=False)  # repr() floats: read back bit for bit
    else:
        frame.to_parquet(path)
    trace = load_trace(path)
    assert trace.axis_names == (
        "x",
        "y",
        "z",
        "joint1",
        "joint2",
        "joint3",
        "joint4",
        "joint5",
        "joint6",
    )
    np.testing.assert_array_equal(trace.force, values)
    np.testing.assert_array_equal(trace.t_s, frame["t"].to_numpy() - 10.0)
    assert trace.dt_s == pytest.approx(0.001, rel=1e-9)
    assert trace.notes == ()


@pytest.mark.parametrize("fmt", FORMATS)
def test_one_group_alone_is_an_input(tmp_path: Path, fmt: str) -> None:
    text = "t,tau1,tau2,tau3,tau4,tau5,tau6\n0,1,2,3,4,5,6\n0.002,1,2,3,4,5,6\n"
    trace = load_trace(table(tmp_path, fmt, text))
    assert trace.axis_names == tuple(f"joint{i}" for i in range(1, 7))
    assert trace.dt_s == 0.002


@pytest.mark.parametrize("fmt", FORMATS)
def test_no_time_column(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "time,fx,fy,fz\n0,1,2,3\n")
    assert refused(path) == f"{path}: no time column 't' (has time, fx, fy, fz)"


@pytest.mark.parametrize("fmt", FORMATS)
def test_no_force_columns(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,force\n0,1\n")
    assert refused(path) == f"{path}: no force columns: fx, fy, fz and/or tau1..tau6 are needed"


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_group_comes_whole(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,tau1\n0,1,2,3\n")
    assert refused(path) == f"{path}: no column fz: fx, fy, fz come together (has fx, fy)"
    path = table(tmp_path, fmt, "t,fx,fy,fz,tau1,tau2,tau3,tau4,tau6\n0,1,2,3,4,5,6,7,8\n")
    assert refused(path) == (
        f"{path}: no column tau5: tau1, tau2, tau3, tau4, tau5, tau6 come together "
        "(has tau1, tau2, tau3, tau4, tau6)"
    )


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_value_that_is_not_a_number(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n0.001,1,2 N,3\n")
    assert refused(path) == f"{where(path, 'fy', 1)}: '2 N' is not a number"


@pytest.mark.parametrize("fmt", FORMATS)
def test_unsorted_times(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n0.002,1,2,3\n0.001,1,2,3\n")
    assert refused(path, resample=True) == (
        f"{where(path, 't', 2)}: time 0.001 s is before row 1's 0.002 s; times must increase"
    )


@pytest.mark.parametrize("fmt", FORMATS)
def test_duplicate_times(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n0.001,1,2,3\n0.001,4,5,6\n0.002,1,2,3\n")
    assert refused(path, resample=True) == (
        f"{where(path, 't', 2)}: time 0.001 s repeats row 1; times must increase"
    )


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_missing_time(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n,1,2,3\n")
    assert refused(path, resample=True) == f"{where(path, 't', 1)}: time is missing"


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_nan_row_is_refused_unless_resampled(tmp_path: Path, fmt: str) -> None:
    text = "t,fx,fy,fz\n0,0,0,0\n0.001,1,2,3\n0.002,1,,3\n0.003,3,4,5\n0.004,4,5,6\n"
    path = table(tmp_path, fmt, text)
    assert refused(path) == (
        f"{where(path, 'fy', 2)}: missing (NaN or empty); pass --resample to drop such rows "
        "and interpolate"
    )
    trace = load_trace(path, resample=True)
    np.testing.assert_allclose(trace.t_s, [0.0, 0.001, 0.002, 0.003, 0.004])
    np.testing.assert_allclose(trace.force[2], [2.0, 3.0, 4.0])  # halfway between its neighbours
    assert trace.notes[0] == f"{path}: dropped 1 row with missing force"


@pytest.mark.parametrize("fmt", FORMATS)
def test_infinite_force_is_refused_even_when_resampling(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n0.001,1,2,inf\n")
    assert refused(path, resample=True) == f"{where(path, 'fz', 1)}: inf: infinite force is refused"


@pytest.mark.parametrize("fmt", FORMATS)
def test_non_uniform_sampling_is_refused_with_the_jitter_unless_resampled(
    tmp_path: Path, fmt: str
) -> None:
    text = "t,fx,fy,fz\n0,0,0,0\n0.001,1,1,1\n0.002,2,2,2\n0.0035,3.5,3.5,3.5\n0.0045,0,0,0\n"
    path = table(tmp_path, fmt, text)
    assert refused(path) == (
        f"{where(path, 't', 3)}: non-uniform sampling: a step of 0.0015 s where the median is "
        "0.001 s (largest deviation 50 % of the period, more than 1 %); pass --resample to "
        "interpolate onto a uniform 0.001 s grid"
    )
    trace = load_trace(path, resample=True)
    np.testing.assert_allclose(trace.t_s, [0.0, 0.001, 0.002, 0.003, 0.004], atol=1e-15)
    np.testing.assert_allclose(trace.force[:, 0], [0.0, 1.0, 2.0, 3.0, 1.75])
    assert trace.dt_s == pytest.approx(0.001)
    assert "resampled onto a uniform 0.001 s grid (5 ticks" in trace.notes[0]


def test_jitter_within_the_tolerance_keeps_the_times_as_given(tmp_path: Path) -> None:
    t = np.arange(100) * 0.001
    t[1:-1] += 0.5 * UNIFORM_TOLERANCE * 0.001 * np.sin(np.arange(1, 99))
    frame = pd.DataFrame({"t": t, "fx": 1.0, "fy": 2.0, "fz": 3.0})
    path = tmp_path / "jitter.parquet"
    frame.to_parquet(path)
    trace = load_trace(path)
    np.testing.assert_array_equal(trace.t_s, t)
    assert trace.notes == ()


@pytest.mark.parametrize("fmt", FORMATS)
def test_fewer_than_two_rows(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n")
    assert refused(path) == f"{path}: 1 row; at least two are needed"


def test_unreadable_and_unknown_inputs(tmp_path: Path) -> None:
    broken = tmp_path / "broken.parquet"
    broken.write_bytes(b"not parquet at all")
    assert refused(broken).startswith(f"{broken}: cannot read as Parquet: ")
    other = tmp_path / "trace.txt"
    other.write_text("t,fx\n")
    assert (
        refused(other) == f"{other}: unknown input type '.txt'; known: .mcap, .csv, .parquet, .pq"
    )
    missing = tmp_path / "missing.csv"
    assert refused(missing).startswith(f"{missing}: cannot read as CSV: ")


def _parquet(tmp_path: Path, t: object, fx: object = 1.0) -> Path:
    path = tmp_path / "input.parquet"
    pd.DataFrame({"t": t, "fx": fx, "fy": 0.0, "fz": 0.0}).to_parquet(path)
    return path


@pytest.mark.parametrize(
    "t",
    [
        pd.date_range("2026-01-01", periods=5, freq="1ms"),  # written as timestamp[us]
        pd.date_range("2026-01-01", periods=5, freq="1ms").astype("datetime64[ms]"),
        # across the switch to summer time: the zone's clock jumps, the time does not
        pd.date_range("2026-03-29 00:59:59.998", periods=5, freq="1ms", tz="Europe/Berlin"),
        pd.to_timedelta(np.arange(5) + 1000, unit="ms"),
    ],
    ids=["timestamp us", "timestamp ms", "timestamp with zone", "duration"],
)
def test_timestamps_and_durations_are_seconds_from_the_first_row(tmp_path: Path, t: object) -> None:
    trace = load_trace(_parquet(tmp_path, t))
    np.testing.assert_array_equal(trace.t_s, np.arange(5) / 1000)
    assert trace.dt_s == pytest.approx(0.001, rel=1e-12)
    assert trace.duration_s < 1.0


def test_a_missing_timestamp_is_refused(tmp_path: Path) -> None:
    t = pd.Series(pd.date_range("2026-01-01", periods=5, freq="1ms")).where(lambda s: s.index != 2)
    path = _parquet(tmp_path, t)
    assert refused(path) == f"{path}: column t, row 2: time is missing"


@pytest.mark.parametrize(
    ("t", "fx", "message"),
    [
        (
            [False, True, True],
            1.0,
            "column t has type bool; times must be numbers (s) or timestamps",
        ),
        (
            [0.0, 0.001, 0.002],
            pd.date_range("2026-01-01", periods=3, freq="1ms"),
            "column fx has type datetime64[us]; forces must be numbers (N or N*m)",
        ),
        (
            [0.0, 0.001, 0.002],
            [True, False, True],
            "column fx has type bool; forces must be numbers (N or N*m)",
        ),
        (
            [datetime.date(2026, 1, d) for d in (1, 2, 3)],
            1.0,
            "column t, row 0: datetime.date(2026, 1, 1) is not a number",
        ),
    ],
    ids=["bool times", "timestamp forces", "bool forces", "dates"],
)
def test_columns_of_other_types_are_refused_naming_the_type(
    tmp_path: Path, t: object, fx: object, message: str
) -> None:
    path = _parquet(tmp_path, t, fx)
    assert refused(path) == f"{path}: {message}"


@pytest.mark.parametrize("fmt", FORMATS)
def test_times_that_are_not_seconds_are_refused(tmp_path: Path, fmt: str) -> None:
    path = table(tmp_path, fmt, "t,fx,fy,fz\n0,1,2,3\n1,1,2,3\n2,1,2,3\n")  # ms, as integers
    assert refused(path) == (
        f"{path}: column t: a period (median step) of 1 s; an admittance loop runs faster than "
        "1 Hz: are the times in s?"
    )


def test_a_resampling_grid_too_big_for_memory_is_refused_before_it_is_made(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = table(tmp_path, "csv", "t,fx,fy,fz\n0,1,2,3\n0.001,1,2,3\n0.002,1,2,3\n1e7,1,2,3\n")
    monkeypatch.setattr(tables, "_resampled", None)  # making the grid would fail otherwise
    monkeypatch.setattr(tables.os, "sysconf", lambda name: 1 << 20 if "PAGES" in name else 4096)
    assert refused(path, resample=True) == (
        f"{path}: resampling onto a uniform 0.001 s grid from 0 to 10000000 s makes "
        "10000000001 ticks (the largest gap is 1e+07 s): one run's result would need 1462.2 "
        "GiB, more than this machine's 4.0 GiB"
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "cannot read as CSV: No columns to parse from file"),
        ("t,fx,fy,fz\n", "0 rows; at least two are needed"),
    ],
    ids=["empty file", "header only"],
)
def test_an_empty_table_is_refused(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "empty.csv"
    path.write_text(text)
    assert refused(path) == f"{path}: {message}"
