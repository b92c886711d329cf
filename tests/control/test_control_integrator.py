"""The integrator against independent oracles: scipy's exact discretisation and closed forms."""

import math

import numpy as np
import pytest
from scipy import signal

from hilrig.control import make, simulate

CASES = [  # (m, b, k, dt): paper values, light/heavy damping, critical damping, coarse dt
    (20.0, 150.0, 300.0, 0.002),
    (30.0, 40.0, 150.0, 0.001),
    (1.0, 1.0, 500.0, 0.01),
    (1.0, 250.0, 100.0, 0.05),
    (4.0, 8.0, 4.0, 0.002),  # zeta = 1 exactly
]


@pytest.mark.parametrize(("m", "b", "k", "dt"), CASES)
def test_fixed_law_matches_scipy_zoh_discretisation(
    m: float, b: float, k: float, dt: float
) -> None:
    force = np.random.default_rng(1).normal(scale=3.0, size=4000)
    a = np.array([[0.0, 1.0], [-k / m, -b / m]])
    bb = np.array([[0.0], [1.0 / m]])
    sys_d = signal.cont2discrete((a, bb, np.eye(2), np.zeros((2, 1))), dt, method="zoh")
    _, y, _ = signal.dlsim(sys_d, force)
    result = simulate("fixed", force, dt, {"m": m, "b_d": b, "k_d": k})
    # offset[n] is the state after tick n, which dlsim reports at n + 1.
    np.testing.assert_allclose(result.offset[:-1, 0], y[1:, 0], rtol=0, atol=1e-12 * abs(y).max())
    np.testing.assert_allclose(result.velocity[:-1, 0], y[1:, 1], rtol=0, atol=1e-12 * abs(y).max())


def _step_response(m: float, b: float, k: float, f: float, t: np.ndarray) -> np.ndarray:
    """Closed-form e(t) of m e'' + b e' + k e = f from rest."""
    wn = math.sqrt(k / m)
    zeta = b / (2 * math.sqrt(m * k))
    if zeta < 1:
        wd = wn * math.sqrt(1 - zeta**2)
        decay = np.exp(-zeta * wn * t)
        return (
            f / k * (1 - decay * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t)))
        )
    if zeta == 1:
        return f / k * (1 - np.exp(-wn * t) * (1 + wn * t))
    r1 = -wn * (zeta - math.sqrt(zeta**2 - 1))
    r2 = -wn * (zeta + math.sqrt(zeta**2 - 1))
    return f / k * (1 + (r2 * np.exp(r1 * t) - r1 * np.exp(r2 * t)) / (r1 - r2))


@pytest.mark.parametrize(
    ("m", "b", "k"), [(20.0, 150.0, 300.0), (20.0, 50.0, 300.0), (4.0, 8.0, 4.0)]
)
def test_step_response_matches_closed_form(m: float, b: float, k: float) -> None:
    dt = 0.001
    force = np.full(5000, 10.0)
    result = simulate("fixed", force, dt, {"m": m, "b_d": b, "k_d": k})
    t_after = (np.arange(5000) + 1) * dt
    expected = _step_response(m, b, k, 10.0, t_after)
    np.testing.assert_allclose(result.offset[:, 0], expected, rtol=0, atol=1e-12 * 10.0 / k)


def test_semi_implicit_euler_is_the_textbook_update() -> None:
    m, b, k, dt = 20.0, 150.0, 300.0, 0.002
    force = np.random.default_rng(2).normal(size=500)
    result = simulate("fixed", force, dt, {"m": m, "b_d": b, "k_d": k, "integrator": "euler"})
    e = v = 0.0
    for n, f in enumerate(force):
        v = v + dt * (f - b * v - k * e) / m
        e = e + dt * v
        assert result.offset[n, 0] == pytest.approx(e, rel=1e-12, abs=1e-15)
        assert result.velocity[n, 0] == pytest.approx(v, rel=1e-12, abs=1e-15)


def test_step_and_simulate_give_identical_numbers() -> None:
    force = np.random.default_rng(3).normal(scale=2.0, size=(3000, 3))
    force[1000:1500] += 4.0
    controller = make("adaptive", "adaptive", axes=3, dt=0.001)
    stepped = np.array([controller.step(row).copy() for row in force])
    result = simulate(controller, force)
    assert np.array_equal(stepped, result.offset)
    assert np.array_equal(controller.stiffness, result.stiffness[-1])
    assert np.array_equal(controller.zeta, result.zeta[-1])


def test_simulate_leaves_the_controller_untouched() -> None:
    controller = make("adaptive", "adaptive", axes=1, dt=0.001)
    controller.step([3.0])
    before = controller.velocity.copy()
    simulate(controller, np.ones((100, 1)))
    assert np.array_equal(controller.velocity, before)


def test_reset_returns_to_rest() -> None:
    controller = make("adaptive", "paper-end-effector", axes=2, dt=0.002)
    first = controller.step([5.0, -1.0]).copy()
    controller.step([5.0, -1.0])
    controller.reset()
    assert np.array_equal(controller.step([5.0, -1.0]), first)


def test_one_dimensional_force_is_one_axis() -> None:
    result = simulate("fixed", np.ones(10), 0.001, "paper-end-effector")
    assert result.offset.shape == (10, 1)
