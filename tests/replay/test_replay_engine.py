"""The engine against hilrig.control.simulate (the oracle), both execution paths, the contract."""

from __future__ import annotations

import os

import numpy as np
import pandas as pd
import pytest
from replay_helpers import AXES, EXAMPLE, trace

from hilrig.control import simulate
from hilrig.replay import (
    RUNS_KEY,
    ReplayError,
    Run,
    column_names,
    engine,
    load_trace,
    parse_specs,
    replay,
    run,
)
from hilrig.replay.trace import ForceTrace

QUANTITIES = ("offset", "velocity", "damping", "stiffness", "zeta", "contact")


def assert_equals_simulate(table: pd.DataFrame, source: ForceTrace, name: str, run_: Run) -> None:
    """Every column of run ``name`` equals simulate() on the same input, to the last bit."""
    expected = simulate(run_.law, source.force, source.dt_s, run_.params)
    rows = table[table["run"] == name]
    assert len(rows) == source.ticks
    for quantity in QUANTITIES:
        got = np.stack([rows[f"{quantity}_{a}"].to_numpy() for a in source.axis_names], axis=1)
        np.testing.assert_array_equal(got, getattr(expected, quantity), err_msg=quantity)
    force = np.stack([rows[f"force_{a}"].to_numpy() for a in source.axis_names], axis=1)
    np.testing.assert_array_equal(force, source.force)
    np.testing.assert_array_equal(rows["t_s"].to_numpy(), source.t_s)


@pytest.mark.parametrize(
    "axes",
    [AXES, AXES[:3], AXES[3:]],
    ids=["both groups", "cartesian", "joints"],
)
def test_every_law_equals_simulate_bit_for_bit(axes: tuple[str, ...]) -> None:
    source = trace(axes=axes)
    specs = parse_specs(
        ["adaptive", "variable-stiffness", "fixed", "paper=adaptive"],
        ["paper.cartesian.preset=paper-end-effector", "paper.joint.preset=paper-joint"],
    )
    runs = [Run.from_spec(s, axes) for s in specs]
    table = replay(source, runs, jobs=1)
    assert list(table.columns) == column_names(axes)
    for r in runs:
        assert_equals_simulate(table, source, r.name, r)


def test_a_recorded_session_replays_like_simulate_over_kernel_block_boundaries(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(engine, "BLOCK_TICKS", 1000)  # 3499 ticks: four kernel calls per run
    source = load_trace(EXAMPLE)
    specs = parse_specs(["adaptive", "fixed"])
    table = run(source, specs)
    for spec in specs:
        assert_equals_simulate(table, source, spec.name, Run.from_spec(spec, source.axis_names))


def test_the_process_pool_and_this_process_give_identical_tables() -> None:
    source = trace(ticks=2000)
    specs = parse_specs(["adaptive", "fixed"], sweeps=["adaptive.a1=5:40:3"])
    runs = [Run.from_spec(s, source.axis_names) for s in specs]
    alone = replay(source, runs, jobs=1)
    pooled = replay(source, runs, jobs=2)
    pd.testing.assert_frame_equal(alone, pooled, check_exact=True)
    assert alone.attrs == pooled.attrs


def test_the_table_follows_the_contract() -> None:
    source = trace(ticks=500, axes=AXES[:3])
    specs = parse_specs(["adaptive", "fixed"], ["adaptive.a1=10"])
    table = run(source, specs)
    assert list(table["run"].cat.categories) == ["adaptive.a1=10", "fixed"]
    assert list(table["law"].unique()) == ["adaptive", "fixed"]
    assert table["t_s"].dtype == np.float64
    assert table["offset_x"].dtype == np.float64 and table["contact_x"].dtype == np.int8
    assert len(table) == 2 * 500
    meta = table.attrs[RUNS_KEY]["adaptive.a1=10"]
    assert meta["law"] == "adaptive" and meta["settings"] == {"a1": 10.0}
    assert meta["params"]["a1"] == [10.0, 10.0, 10.0]
    assert meta["params"]["b_d"] == [150.0, 150.0, 150.0]
    assert meta["dt_s"] == 0.002 and meta["axes"] == ["x", "y", "z"]


def test_progress_counts_every_tick_of_every_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(engine, "BLOCK_TICKS", 256)
    seen: list[tuple[str, int, int]] = []
    run(trace(ticks=1000), parse_specs(["adaptive", "fixed"]), progress=lambda *a: seen.append(a))
    done = [d for phase, d, _ in seen if phase == "replay"]
    assert done == sorted(done) and done[-1] == 2000
    assert {total for _, _, total in seen} == {2000}


def test_parameters_that_cannot_be_stable_are_refused_naming_the_run() -> None:
    specs = parse_specs(["adaptive"], ["adaptive.cartesian.a2=1.5"])
    with pytest.raises(ReplayError, match=r"^run adaptive\.cartesian\.a2=1\.5: a2 = 1\.5 on axis"):
        run(trace(ticks=10), specs)


def test_a_table_larger_than_memory_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(engine, "table_bytes", lambda axes, rows: 1 << 60)
    with pytest.raises(ReplayError, match="GiB table, more than this machine's"):
        run(trace(ticks=10), parse_specs(["fixed"]))


def test_the_pool_is_chosen_only_where_it_measured_faster() -> None:
    def runs(*names: str) -> list[Run]:
        sets = [
            f"{n}.{g}.preset=paper-{p}"
            for n in names
            for g, p in (("cartesian", "end-effector"), ("joint", "joint"))
        ]
        return [Run.from_spec(s, AXES) for s in parse_specs([f"{n}={n[:-1]}" for n in names], sets)]

    cores = min(2, len(os.sched_getaffinity(0)))
    bare = runs("adaptive1", "variable-stiffness2")  # bare law: every tick a full step
    assert engine.choose_jobs(bare, 10**7) == cores
    assert engine.choose_jobs(bare, 1000) == 1  # short: forking costs more
    assert engine.choose_jobs(bare[:1] + runs("fixed3"), 10**7) == 1  # fixed takes quiet ticks
    loop = [Run.from_spec(s, AXES) for s in parse_specs()]  # state machines: memory-bound
    assert engine.choose_jobs(loop, 10**9) == 1


def test_runs_built_by_hand_need_unique_names() -> None:
    (spec,) = parse_specs(["fixed"])
    same = Run.from_spec(spec, AXES)
    with pytest.raises(ReplayError, match=r"^run names repeat: fixed$"):
        replay(trace(ticks=10), [same, same])


def _pushed(force_n: float) -> ForceTrace:
    force = np.zeros((3000, 3))
    force[100:, 0] = force_n
    return ForceTrace(np.arange(3000) * 0.002, force, AXES[:3], "inline", 0.002)


@pytest.mark.parametrize("jobs", [1, 2], ids=["this process", "pool"])
def test_a_result_that_is_not_finite_is_refused_naming_the_run_column_and_tick(jobs: int) -> None:
    specs = parse_specs(["adaptive", "fixed"], ["fixed.m=1", "fixed.b_d=0.1", "fixed.k_d=1"])
    with pytest.raises(ReplayError) as caught:
        run(_pushed(1e308), specs, jobs=jobs)  # finite, valid, but the offset overflows
    assert str(caught.value) == (
        "run fixed.m=1.b_d=0.1.k_d=1 (fixed): column offset_x is inf at tick 1490 "
        "(t = 2.98 s), its first value that is not finite; the result is refused"
    )
    assert run(_pushed(1e3), specs, jobs=jobs)["offset_x"].notna().all()  # the same, sane


def test_a_damping_ratio_that_is_not_finite_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    ratio = engine.damping_ratio_rows

    def broken(*args: np.ndarray) -> None:
        ratio(*args)
        args[-1][1, 7] = np.nan

    monkeypatch.setattr(engine, "damping_ratio_rows", broken)
    with pytest.raises(ReplayError) as caught:
        run(trace(ticks=10, axes=AXES[:3]), parse_specs(["fixed"]), jobs=1)
    assert str(caught.value) == (
        "run fixed (fixed): column zeta_y is nan at tick 7 (t = 0.014 s), its first value "
        "that is not finite; the result is refused"
    )


def test_too_big_a_table_is_refused_before_any_run_is_built(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(engine, "table_bytes", lambda axes, rows: 1 << 60)
    monkeypatch.setattr(Run, "from_spec", None)  # building a run would fail otherwise
    with pytest.raises(ReplayError) as caught:
        run(trace(ticks=10), parse_specs(["fixed"]))
    assert str(caught.value).startswith("1 run of 10 ticks need a 1073741824.0 GiB table, ")
