"""Replays into an Arena (a sweep worker's memory, reused): the same tables as fresh memory,
bit for bit, whatever the memory held before, and never over a table still in use."""

from __future__ import annotations

import gc

import numpy as np
import pandas as pd
from replay_helpers import AXES, trace

from hilrig.replay import Run, parse_specs, replay
from hilrig.replay.blocks import Arena

SPECS = parse_specs(["adaptive", "fixed"], ["adaptive.a1=12"])


def runs() -> list[Run]:
    return [Run.from_spec(s, AXES) for s in SPECS]


def address(table: pd.DataFrame) -> int:
    return int(table[f"offset_{AXES[0]}"].to_numpy().ctypes.data)


def test_a_reused_arena_gives_the_tables_of_fresh_memory_whatever_it_held() -> None:
    source = trace(ticks=2500)
    fresh = replay(source, runs(), jobs=1)
    arena = Arena()
    poison, new = arena.take(1 << 22)  # larger than the tables: handed out again below
    assert new
    poison[:] = 0xFF  # every float a NaN, every contact code -1
    del poison
    first = replay(source, runs(), jobs=1, arena=arena)
    where = address(first)
    pd.testing.assert_frame_equal(first, fresh, check_exact=True)
    del first
    gc.collect()
    again = replay(trace(ticks=2000), runs()[:1], jobs=1, arena=arena)  # smaller: same memory
    assert address(again) == where
    pd.testing.assert_frame_equal(again, replay(trace(ticks=2000), runs()[:1], jobs=1))


def test_an_arena_never_hands_out_memory_a_table_still_uses() -> None:
    arena = Arena()
    kept = replay(trace(ticks=2000), runs(), jobs=1, arena=arena)
    copy = kept.copy(deep=True)
    other = replay(trace(ticks=2000, dt_s=0.001), runs()[:1], jobs=1, arena=arena)
    assert not np.shares_memory(
        kept[f"offset_{AXES[0]}"].to_numpy(), other[f"offset_{AXES[0]}"].to_numpy()
    )
    pd.testing.assert_frame_equal(kept, copy, check_exact=True)


def test_an_arena_grows_when_a_table_needs_more() -> None:
    arena = Arena()
    small, _ = arena.take(4096)
    del small
    big, new = arena.take(1 << 20)
    assert new and big.shape == (1 << 20,)
    del big
    again, new = arena.take(1 << 19)
    assert not new and again.shape == (1 << 19,)
