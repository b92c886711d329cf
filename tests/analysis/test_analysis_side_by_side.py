"""A replay table's runs are read without a copy where their columns lie evenly spaced in one
buffer: the same values as the interleaved copy (bit for bit), read-only, kept alive by the run
(a sweep worker's arena never writes over them), and a copy wherever the columns are not so."""

from __future__ import annotations

import gc
import itertools
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.analysis import runs_from_frame
from hilrig.analysis.sources import side_by_side
from hilrig.replay import Run, parse_specs, replay
from hilrig.replay.blocks import Arena

sys.path.insert(0, str(Path(__file__).parents[1] / "replay"))
from replay_helpers import AXES, trace

SPECS = parse_specs(["adaptive", "fixed"])


def interleaved(table: pd.DataFrame, quantity: str, rows: slice) -> np.ndarray:
    return table[[f"{quantity}_{a}" for a in AXES]].to_numpy(np.float64)[rows]


def test_a_replay_s_runs_are_views_of_its_table_with_the_interleaved_values() -> None:
    table = replay(trace(ticks=3000), [Run.from_spec(s, AXES) for s in SPECS], jobs=1)
    runs = runs_from_frame(table)
    assert [r.name for r in runs] == ["adaptive", "fixed"]
    for index, run in enumerate(runs):
        rows = slice(index * 3000, (index + 1) * 3000)
        for quantity, values in (
            ("force", run.force),
            ("offset", run.offset),
            ("velocity", run.offset_rate),
        ):
            assert np.array_equal(values, interleaved(table, quantity, rows))
            assert np.shares_memory(values, table[f"{quantity}_{AXES[-1]}"].to_numpy())
            assert not values.flags.writeable


def test_a_run_keeps_its_memory_from_the_arena_s_next_replay() -> None:
    arena = Arena()
    table = replay(trace(ticks=2000), [Run.from_spec(SPECS[0], AXES)], jobs=1, arena=arena)
    (run,) = runs_from_frame(table)
    kept = run.offset.copy()
    del table
    gc.collect()
    other = replay(trace(ticks=2000, dt_s=0.001), [Run.from_spec(SPECS[1], AXES)], arena=arena)
    assert not np.shares_memory(run.offset, other[f"offset_{AXES[0]}"].to_numpy())
    assert np.array_equal(run.offset, kept)


def test_columns_of_separate_buffers_are_interleaved_into_a_copy() -> None:
    table = replay(trace(ticks=1500), [Run.from_spec(SPECS[0], AXES)], jobs=1)
    columns = {name: table[name].to_numpy().copy() for name in table.columns}
    apart = pd.DataFrame(columns, copy=False)  # without copy=False pandas makes one block
    (run,) = runs_from_frame(apart)
    assert np.array_equal(run.force, interleaved(table, "force", slice(None)))
    assert not any(np.shares_memory(run.force, columns[f"force_{a}"]) for a in AXES)


@settings(max_examples=100, deadline=None)
@given(
    st.integers(1, 6),
    st.integers(1, 40),
    st.integers(0, 7),
    st.lists(st.integers(0, 5), min_size=1, max_size=6),
)
def test_evenly_spaced_rows_of_one_block_are_a_view_and_others_are_not(
    axes: int, ticks: int, pad: int, picks: list[int]
) -> None:
    block = np.random.default_rng(axes * 100 + ticks).normal(size=(axes, ticks + pad))
    columns = [block[i % axes, :ticks] for i in picks]
    steps = {b.ctypes.data - a.ctypes.data for a, b in itertools.pairwise(columns)}
    view = side_by_side(columns)
    if len(steps) <= 1:
        assert view is not None and not view.flags.writeable
        assert np.array_equal(view, np.column_stack(columns))
    else:
        assert view is None
    if len(columns) > 1:  # separate buffers, even if they happened to lie evenly spaced
        assert side_by_side([c.copy() for c in columns]) is None
    assert side_by_side([block[i % axes, ::2] for i in picks]) is None  # not contiguous
