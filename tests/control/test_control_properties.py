"""Invariants over arbitrary bounded force traces (hypothesis)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hilrig.control import Law, bounds, make, resolve_params, simulate

PRESETS = ["paper-end-effector", "paper-joint", "adaptive", "adaptive-joint"]
LAWS = ["fixed", "variable-stiffness", "adaptive"]

force_traces = st.integers(1, 1500).flatmap(
    lambda n: arrays(np.float64, (n, 3), elements=st.floats(-50.0, 50.0, width=64))
)


@settings(max_examples=150, deadline=None)
@given(force=force_traces, law=st.sampled_from(LAWS), preset=st.sampled_from(PRESETS))
def test_bounded_force_gives_bounded_offsets_and_parameters_in_range(
    force: np.ndarray, law: str, preset: str
) -> None:
    result = simulate(law, force, 0.002, preset)
    found = bounds(Law(law), resolve_params(preset), 3)
    f_max = max(float(np.abs(force).max()), 1e-9)
    assert np.isfinite(result.offset).all()
    # A stable second-order axis overshoots its static deflection f/k by less than 100 %.
    assert (np.abs(result.offset) <= 2.0 * f_max / found.k_min + 1e-12).all()
    assert (result.damping >= found.b_min - 1e-12).all()
    assert (result.damping <= found.b_max).all()
    assert (result.stiffness >= found.k_min - 1e-12).all()
    assert (result.stiffness <= found.k_max).all()


@settings(max_examples=100, deadline=None)
@given(force=force_traces, preset=st.sampled_from(["adaptive", "adaptive-joint"]))
def test_theorem_1_guard_holds_on_every_tick(force: np.ndarray, preset: str) -> None:
    result = simulate("adaptive", force, 0.001, preset)
    found = bounds(Law.ADAPTIVE, resolve_params(preset), 3)
    growth = np.exp(found.gamma * 0.001)
    k = np.vstack([found.k_max[None, :], result.stiffness])  # k before the first tick is k_d
    assert (k[1:] <= k[:-1] * growth * (1 + 1e-15)).all()


@settings(max_examples=60, deadline=None)
@given(force=force_traces, law=st.sampled_from(LAWS))
def test_live_steps_equal_the_offline_simulation(force: np.ndarray, law: str) -> None:
    controller = make(law, "adaptive", axes=3, dt=0.001)
    stepped = np.array([controller.step(row).copy() for row in force])
    assert np.array_equal(stepped, simulate(controller, force).offset)
