"""The bare law over blocks of ticks (``blocks.py``) against the same law tick by tick: ``step``
runs one tick per call (``bare.py``'s loop), ``simulate`` and ``run_into`` whole blocks. Every
output must be the same to the bit, whatever the reading, guard, grouping or block boundary, and
a non-finite force must stop both at the same tick with the same state."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.control import (
    OUTPUTS,
    AdmittanceParams,
    NonFiniteForceError,
    combine,
    make,
    preset,
    simulate,
)
from hilrig.control.blocks import BLOCK
from hilrig.control.params import BetaReading, ChiReading

DT = 0.001
NEAR = preset("paper-end-effector")
FAR = replace(NEAR, m=1.0, k_d=5e4, b_d=400.0)  # |q| > 1e-3: never the near-critical series
MIXED = combine((NEAR, 3), (FAR, 2), (preset("paper-joint"), 4))
CASES = {
    "paper": combine((NEAR, 3), (preset("paper-joint"), 6)),
    "mixed": MIXED,
    "guard": replace(MIXED, rate_guard=True, gamma=0.5),
    "abs-max": replace(MIXED, chi=ChiReading.ABS, beta_reading=BetaReading.MAX),
    "groups": replace(
        MIXED, chi=ChiReading.GROUP_SQUARE, groups=(0, 0, 0, 1, 1, 2, 2, 2, 2), rate_guard=True
    ),
}


def session(ticks: int, seed: int) -> np.ndarray:
    """Sensor noise with pushes above delta, some far enough to saturate tanh."""
    rng = np.random.default_rng(seed)
    force = rng.normal(scale=0.05, size=(ticks, 9))
    for start in rng.integers(0, ticks - 200, size=4):
        axis = rng.integers(0, 9)
        force[start : start + 200, axis] += rng.uniform(0.1, 8.0) * np.sin(
            np.linspace(0.0, np.pi, 200)
        )
    return force


def ticks_one_by_one(law: str, params: AdmittanceParams, force: np.ndarray) -> np.ndarray:
    """(outputs + contact, T, A) from one ``step`` per tick."""
    controller = make(law, params, dt=DT)
    rows = np.empty((len(OUTPUTS) + 1, *force.shape))
    for n, row in enumerate(force):
        controller.step(row)
        rows[:, n] = (
            controller.offset,
            controller.velocity,
            controller.damping,
            controller.stiffness,
            controller.contact,
        )
    return rows


def assert_same(result: object, rows: np.ndarray) -> None:
    for q, quantity in enumerate((*OUTPUTS, "contact")):
        np.testing.assert_array_equal(getattr(result, quantity), rows[q], err_msg=quantity)


@pytest.mark.parametrize("law", ["adaptive", "variable-stiffness"])
@pytest.mark.parametrize("case", list(CASES))
def test_blocks_equal_ticks_one_by_one(law: str, case: str) -> None:
    force = session(3 * BLOCK + 37, seed=len(case))
    assert_same(simulate(law, force, DT, CASES[case]), ticks_one_by_one(law, CASES[case], force))


@settings(max_examples=15, deadline=None)
@given(
    case=st.sampled_from(list(CASES)),
    chunks=st.lists(st.integers(1, 2 * BLOCK + 3), min_size=1, max_size=6),
    seed=st.integers(0, 2**16),
)
def test_run_into_strided_chunks_equal_simulate(case: str, chunks: list[int], seed: int) -> None:
    """Chunks below and above the blocked path's threshold, into a table's strided columns."""
    ticks = sum(chunks)
    force = session(max(ticks, 201), seed)[:ticks]
    expected = simulate("adaptive", force, DT, CASES[case])
    controller = make("adaptive", CASES[case], dt=DT)
    columns = np.zeros((9, len(OUTPUTS) + 1, ticks))  # (axes, quantities, ticks)
    contact = np.zeros((9, ticks), dtype=np.int8)
    start = 0
    for size in chunks:
        rows = slice(start, start + size)
        out = columns[:, : len(OUTPUTS), rows].transpose(1, 2, 0)
        controller.run_into(force[rows], out, contact[:, rows].T)
        start += size
    for q, quantity in enumerate(OUTPUTS):
        np.testing.assert_array_equal(columns[:, q].T, getattr(expected, quantity))
    np.testing.assert_array_equal(contact.T, expected.contact)


@pytest.mark.parametrize("bad_tick", [0, 1, BLOCK - 1, BLOCK, BLOCK + 5, 2 * BLOCK + 40])
@pytest.mark.parametrize("case", ["mixed", "groups"])
def test_non_finite_force_stops_blocks_where_ticks_stop(bad_tick: int, case: str) -> None:
    force = session(3 * BLOCK, seed=bad_tick)
    force[bad_tick, 4] = np.inf
    force[bad_tick, 6] = np.nan  # the first in the row is reported
    blocks = make("adaptive", CASES[case], dt=DT)
    out = np.zeros((len(OUTPUTS), *force.shape))
    with pytest.raises(NonFiniteForceError, match=rf"^force\[{bad_tick}, 4\] is inf"):
        blocks.run_into(force, out, np.zeros(force.shape, dtype=np.int8))
    assert not out[:, bad_tick:].any()
    ticks = make("adaptive", CASES[case], dt=DT)
    for row in force[:bad_tick]:
        ticks.step(row)
    with pytest.raises(NonFiniteForceError):
        ticks.step(force[bad_tick])
    for name in ("offset", "velocity", "damping", "stiffness", "contact"):
        np.testing.assert_array_equal(getattr(blocks, name), getattr(ticks, name), err_msg=name)
    # the packed state itself, caches and group scratch included, then the same continuation
    np.testing.assert_array_equal(blocks.kernel_arrays().S, ticks.kernel_arrays().S)
    np.testing.assert_array_equal(blocks.kernel_arrays().G, ticks.kernel_arrays().G)
    rest = force[bad_tick + 1 :]
    out_rest = np.empty((len(OUTPUTS), *rest.shape))
    blocks.run_into(rest, out_rest, np.empty(rest.shape, dtype=np.int8))
    for n, row in enumerate(rest):
        np.testing.assert_array_equal(ticks.step(row), out_rest[0, n])
