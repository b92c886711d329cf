"""The bare law's kernel path (no state machine; ``kernel.run_bare``) against a tick-by-tick
oracle: the law's (b, k) from ``gains`` (the guard applied here), each tick's Phi and Gamma from
``scipy.linalg.expm`` of the augmented matrix, the state integrated in Python. The axes mix the
near-critical series with the other discretisations, b moving above delta and tanh saturating,
so the phases' fall-back to the full discretisation is exercised on the same ticks."""

from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from hilrig.control import AdmittanceParams, combine, gains, preset, simulate
from hilrig.control.params import ChiReading

DT_S = 0.001


def _oracle(
    law: str, params: AdmittanceParams, force: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets, damping and stiffness per tick, from expm of [[A, B], [0, 0]] dt."""
    ticks, axes = force.shape
    b_law, k_law = gains(law, force, params)
    m = params.per_axis("m", axes)
    k_prev = params.per_axis("k_d", axes).astype(float)
    growth = np.exp(params.per_axis("gamma", axes) * DT_S)  # the guard's tests set gamma
    state = np.zeros((axes, 2))
    offset, damping, stiffness = (np.empty((ticks, axes)) for _ in range(3))
    for n in range(ticks):
        for i in range(axes):
            b, k = b_law[n, i], k_law[n, i]
            if params.rate_guard:
                k = min(k, k_prev[i] * growth[i])
            k_prev[i] = k
            augmented = np.zeros((3, 3))
            augmented[:2, :2] = [[0.0, 1.0], [-k / m[i], -b / m[i]]]
            augmented[1, 2] = 1.0 / m[i]
            exp = expm(augmented * DT_S)
            state[i] = exp[:2, :2] @ state[i] + exp[:2, 2] * force[n, i]
            offset[n, i], damping[n, i], stiffness[n, i] = state[i, 0], b, k
    return offset, damping, stiffness


@settings(max_examples=25, deadline=None)
@given(
    law=st.sampled_from(["adaptive", "variable-stiffness"]),
    chi=st.sampled_from(list(ChiReading)),
    stiff_n_m=st.floats(300.0, 1e6),  # |q| > 1e-3 above about 1.3e3 N/m: no series
    seed=st.integers(0, 2**16),
)
def test_bare_path_matches_expm_tick_by_tick(
    law: str, chi: ChiReading, stiff_n_m: float, seed: int
) -> None:
    near = preset("paper-end-effector")
    far = replace(near, m=1.0, k_d=stiff_n_m, b_d=400.0)
    params = replace(combine((near, 2), (far, 2)), chi=chi)
    rng = np.random.default_rng(seed)
    force = rng.normal(scale=0.05, size=(300, 4))
    force[100:180, rng.integers(0, 4)] += np.linspace(0.0, 6.0, 80)  # above delta, tanh = 1
    result = simulate(law, force, DT_S, params)
    offset, damping, stiffness = _oracle(law, params, force)
    np.testing.assert_array_equal(result.damping, damping)
    np.testing.assert_array_equal(result.stiffness, stiffness)
    scale = np.abs(offset).max(axis=0)
    np.testing.assert_allclose(result.offset, offset, rtol=0, atol=1e-9 * scale.max())
    above = np.abs(force) > 0.2
    groups = np.stack([above[:, :2].any(axis=1), above[:, 2:].any(axis=1)], axis=1)
    expected = np.repeat(groups, 2, axis=1).astype(np.int8)
    np.testing.assert_array_equal(result.contact, expected)  # ContactState CONTACT is 1


def test_rate_guard_limits_stiffness_growth_on_the_bare_path() -> None:
    params = replace(preset("paper-end-effector"), rate_guard=True, gamma=1.0)
    force = np.zeros((400, 1))
    force[:100, 0] = 5.0  # chi = 1: k drops to 0.3 k_d at once, then must climb back slowly
    result = simulate("adaptive", force, DT_S, params)
    offset, _, stiffness = _oracle("adaptive", params, force)
    np.testing.assert_array_equal(result.stiffness, stiffness)
    assert result.stiffness[100, 0] < 300.0  # still climbing a tick after the push
    np.testing.assert_allclose(result.offset, offset, rtol=0, atol=1e-9 * abs(offset).max())
