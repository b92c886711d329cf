"""Result files: the per-axis quantities float32 within their documented rounding error (the
table in memory as oracle), read by plain pyarrow and pandas with the metadata, float64 on
request or where float32 cannot hold a value, and analysed like the table in memory."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from replay_helpers import EXAMPLE, trace

from hilrig.analysis import Analysis, analyze, load_replay, runs_from_frame
from hilrig.replay import INPUT_KEY, RUNS_KEY, ReplayError, load_trace, outputs, parse_specs, run
from hilrig.replay.outputs import load_results, write_parquet
from hilrig.replay.results import (
    FLOAT32_ABSOLUTE_ERROR,
    FLOAT32_RELATIVE_ERROR,
    float32_error,
    stored_float32,
)

#: The analysis' times (s): of events and of the ticks metrics pick.
TIMES = ("start_s", "end_s", "time_to_max_offset_s", "recovery_time_s")


@pytest.fixture(scope="module")
def replayed() -> pd.DataFrame:
    return run(load_trace(EXAMPLE), parse_specs(["adaptive", "variable-stiffness", "fixed"]))


@pytest.fixture(scope="module")
def written(replayed: pd.DataFrame, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_parquet(replayed, tmp_path_factory.mktemp("parquet") / "results.parquet")


def test_every_value_read_back_is_within_its_columns_rounding_error(
    replayed: pd.DataFrame, written: Path
) -> None:
    table, runs = load_results(written)
    assert list(table.columns) == list(replayed.columns)
    assert table.dtypes.equals(replayed.dtypes)  # the in-memory types
    schema = pq.read_schema(written)
    narrowed = [str(c) for c in replayed.columns if stored_float32(str(c))]
    assert len(narrowed) == 6 * 9
    for name in map(str, replayed.columns):
        expected, got = replayed[name].to_numpy(), table[name].to_numpy()
        assert not schema.field(name).nullable
        if name in narrowed:
            assert schema.field(name).type == pa.float32()
            error = np.abs(got - expected)
            bound = np.maximum(FLOAT32_RELATIVE_ERROR * np.abs(expected), FLOAT32_ABSOLUTE_ERROR)
            assert (error <= bound).all(), name
            assert error.max() <= float32_error(np.abs(expected).max()), name  # as documented
            np.testing.assert_array_equal(got, expected.astype(np.float32))  # rounded once
        else:
            pd.testing.assert_series_equal(table[name], replayed[name], check_exact=True)
    assert schema.field("t_s").type == pa.float64()
    assert schema.field("contact_x").type == pa.int8()
    assert str(schema.field("law").type) == "dictionary<values=string, indices=int8, ordered=0>"
    assert runs == replayed.attrs[RUNS_KEY] and table.attrs[INPUT_KEY] == replayed.attrs[INPUT_KEY]


def test_plain_pyarrow_and_pandas_read_the_file_and_its_metadata(
    replayed: pd.DataFrame, written: Path
) -> None:
    arrow = pq.read_table(written)
    metadata = arrow.schema.metadata
    assert json.loads(metadata[RUNS_KEY.encode()]) == replayed.attrs[RUNS_KEY]
    assert json.loads(metadata[INPUT_KEY.encode()]) == replayed.attrs[INPUT_KEY]
    frame = pd.read_parquet(written)
    assert frame["offset_x"].dtype == np.float32 and frame["t_s"].dtype == np.float64
    assert list(frame["run"].cat.categories) == ["adaptive", "variable-stiffness", "fixed"]
    assert list(frame["law"].unique()) == ["adaptive", "variable-stiffness", "fixed"]
    table, _ = load_results(written)
    for name in ("force_z", "damping_joint1", "contact_y", "t_s"):
        np.testing.assert_array_equal(frame[name].to_numpy(), arrow.column(name).to_numpy())
        np.testing.assert_array_equal(frame[name].to_numpy(), table[name].to_numpy())


def test_float64_on_request_is_the_table_exactly(replayed: pd.DataFrame, tmp_path: Path) -> None:
    path = write_parquet(replayed, tmp_path / "exact.parquet", precision="float64")
    table, _ = load_results(path)
    pd.testing.assert_frame_equal(table, replayed, check_exact=True)
    assert pq.read_schema(path).field("offset_x").type == pa.float64()
    with pytest.raises(ReplayError, match=r"^precision 'half': known: float32, float64$"):
        write_parquet(replayed, tmp_path / "half.parquet", precision="half")  # type: ignore[arg-type]
    assert not (tmp_path / "half.parquet").exists()


def test_row_groups_converted_while_the_last_is_written_hold_every_row(
    replayed: pd.DataFrame, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(outputs, "ROW_GROUP_ROWS", 1000)  # 11 groups, buffers reused 5 times
    path = write_parquet(replayed, tmp_path / "groups.parquet")
    assert pq.ParquetFile(path).metadata.num_row_groups == math.ceil(len(replayed) / 1000)
    frame = pd.read_parquet(path)
    for name in map(str, replayed.columns):
        expected = replayed[name].to_numpy()
        if stored_float32(name):
            expected = expected.astype(np.float32)
        np.testing.assert_array_equal(frame[name].to_numpy(), expected, err_msg=name)


def test_a_column_beyond_float32s_range_stays_float64(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    table = run(trace(ticks=40, axes=("x", "y", "z")), parse_specs(["fixed"])).copy()
    table.loc[33, "force_y"] = -1e39  # a finite force float32 would make infinite
    monkeypatch.setattr(outputs, "ROW_GROUP_ROWS", 8)  # found in the 5th block, after 4 written
    path = write_parquet(table, tmp_path / "huge.parquet")
    schema = pq.read_schema(path)
    assert schema.field("force_y").type == pa.float64()
    assert schema.field("force_x").type == schema.field("offset_y").type == pa.float32()
    back, _ = load_results(path)
    np.testing.assert_array_equal(back["force_y"].to_numpy(), table["force_y"].to_numpy())
    assert back.loc[33, "force_y"] == -1e39
    np.testing.assert_array_equal(back["force_x"], table["force_x"].to_numpy().astype(np.float32))


def test_analysis_of_the_file_measures_like_the_table_in_memory(
    replayed: pd.DataFrame, written: Path
) -> None:
    stored = dataclasses.replace(load_replay(written), body_region="hand")  # verdicts too
    in_memory = dataclasses.replace(stored, runs=runs_from_frame(replayed))
    from_file, oracle = analyze(stored), analyze(in_memory)
    assert len(from_file.events) == len(oracle.events) > 0
    assert len(from_file.metrics) == len(oracle.metrics) > 0
    assert len(from_file.verdicts) == len(oracle.verdicts) == 3 * len(oracle.events)
    dt_s = float(replayed.attrs[INPUT_KEY]["dt_s"])
    for kind in ("events", "metrics", "tracking", "verdicts"):
        for got, expected in zip(_of(from_file, kind), _of(oracle, kind), strict=True):
            _assert_close(dataclasses.asdict(got), dataclasses.asdict(expected), dt_s)


def _of(analysis: Analysis, kind: str) -> tuple[Any, ...]:
    items: tuple[Any, ...] = getattr(analysis, kind)
    return items


def _assert_close(got: dict[str, Any], expected: dict[str, Any], dt_s: float) -> None:
    """Floats within float32's rounding carried through the metric (1e-6 relative); times (s)
    equal, or one tick apart where a tick was chosen by comparing values that are closer than
    their rounding (the largest |offset| on a flat peak: its value agrees all the same)."""
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        if key in TIMES and value is not None:
            assert got[key] == pytest.approx(value, abs=dt_s * 1.001), key
        elif isinstance(value, float):
            assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-12, nan_ok=True), key
        else:
            assert got[key] == value, key
