"""Invalid or unstable parameters are refused before any motion, with exact messages."""

import itertools

import numpy as np
import pytest

from hilrig.control import (
    AdmittanceParams,
    NonFiniteForceError,
    ParameterError,
    combine,
    make,
    preset,
    resolve_params,
    simulate,
    stability_report,
)

EE = "paper-end-effector"


@pytest.mark.parametrize(
    ("law", "overrides", "message"),
    [
        ("fixed", {"m": 0.0}, "m = 0 on axis 0 must be > 0 (virtual inertia)"),
        (
            "fixed",
            {"b_d": -1.0},
            "b_d = -1 on axis 0 must be > 0 (a fixed-parameter axis is stable iff m, b, k > 0)",
        ),
        (
            "fixed",
            {"k_d": (300.0, 0.0)},
            "k_d = 0 on axis 1 must be > 0 (a fixed-parameter axis is stable iff m, b, k > 0)",
        ),
        (
            "variable-stiffness",
            {"a2": 1.0},
            "a2 = 1 on axis 0 must be in [0, 1) so that k_min = (1 - a2)*k_d > 0",
        ),
        (
            "adaptive",
            {"beta": 150.0},
            "beta = 150 on axis 0 must be < b_d so that the smallest damping b_d - beta stays > 0",
        ),
        ("adaptive", {"a1": -2.0}, "a1 = -2 on axis 0 must be >= 0"),
        ("fixed", {"m": float("nan")}, "m = nan on axis 0 must be finite"),
        (
            "adaptive",
            {"rate_guard": True, "gamma": 4.0},
            "gamma = 4 on axis 0 must be < 2*b_min*k_min/(m*k_max) (Theorem 1), here 3.6 1/s",
        ),
        (
            "fixed",
            {"integrator": "euler", "m": 0.01},
            "k_max*dt^2/m + 2*b_max*dt/m = 60.12 on axis 0 must be < 4 for semi-implicit Euler "
            "to be stable (use a smaller dt or integrator 'zoh')",
        ),
    ],
)
def test_unstable_parameters_are_refused(law: str, overrides: dict, message: str) -> None:
    axes = 2 if isinstance(overrides.get("k_d"), tuple) else 1
    with pytest.raises(ParameterError) as err:
        make(law, {"preset": EE, **overrides}, axes=axes, dt=0.002)
    assert str(err.value) == message


def test_a2_is_not_checked_for_the_fixed_law() -> None:
    make("fixed", {"preset": EE, "a2": 5.0}, axes=1, dt=0.002)


def test_unknown_names_are_refused() -> None:
    with pytest.raises(ParameterError, match=r"^unknown parameter 'k'; known: m, b_d, k_d"):
        resolve_params({"preset": EE, "k": 1.0})
    with pytest.raises(ParameterError, match=r"^unknown preset 'paper'; known: adaptive, "):
        make("fixed", "paper", axes=1)
    with pytest.raises(ParameterError, match=r"^law 'admittance' is not one of: fixed, "):
        make("admittance", EE, axes=1)
    with pytest.raises(ParameterError, match=r"^chi = 'cube' is not one of: square, abs, "):
        resolve_params({"preset": EE, "chi": "cube"})


def test_dict_without_preset_needs_the_physical_parameters() -> None:
    with pytest.raises(ParameterError, match=r"^params need b_d, k_d \(or a 'preset'"):
        resolve_params({"m": 1.0})
    assert resolve_params({"m": 1.0, "b_d": 2.0, "k_d": 3.0}).a1 == 0.0


def test_axes_come_from_per_axis_parameters_or_must_be_given() -> None:
    assert make("fixed", AdmittanceParams(m=(1.0, 2.0), b_d=1.0, k_d=1.0)).axes == 2
    with pytest.raises(ParameterError, match=r"^axes is required"):
        make("fixed", EE)
    with pytest.raises(ParameterError, match=r"^params are given for 2 axes but the input has 3"):
        simulate("fixed", np.zeros((5, 3)), 0.001, AdmittanceParams(m=(1.0, 2.0), b_d=1, k_d=1))


def test_combine_stacks_groups_and_rejects_mixed_options() -> None:
    both = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6))
    assert both.groups == (0, 0, 0, 1, 1, 1, 1, 1, 1)
    assert both.m == (20.0,) * 3 + (30.0,) * 6
    with pytest.raises(ParameterError, match=r"^cannot combine params with different state_mach"):
        combine((preset("adaptive"), 3), (preset("paper-joint"), 6))


def test_dt_must_be_positive() -> None:
    with pytest.raises(ParameterError, match=r"^dt = 0.0 s must be finite and > 0$"):
        make("fixed", EE, axes=1, dt=0.0)


def test_values_of_the_wrong_kind_are_one_line_parameter_errors() -> None:
    cases = [
        (lambda: make("fixed", EE, axes=-1), "axes = -1 must be >= 1"),
        (
            lambda: stability_report("pid", EE, 1, 0.001),
            "law 'pid' is not one of: fixed, variable-stiffness, adaptive",
        ),
        (lambda: resolve_params({"preset": EE, "m": ["a"]}), "m = ['a'] must be numbers"),
        (
            lambda: AdmittanceParams(m=1, b_d=1, k_d=1, groups=("a",)),
            "groups = ('a',) must be integers",
        ),
    ]
    for call, message in cases:
        with pytest.raises(ParameterError) as err:
            call()
        assert str(err.value) == message


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_force_is_refused_and_never_integrated(bad: float) -> None:
    force = np.zeros((10, 3))
    force[7, 2] = bad
    with pytest.raises(NonFiniteForceError) as err:
        simulate("adaptive", force, 0.002, EE)
    assert str(err.value) == (
        f"force[7, 2] is {bad}: non-finite force is refused and nothing from that tick on "
        "was integrated"
    )
    controller = make("adaptive", EE, axes=3, dt=0.002)
    controller.step([1.0, 2.0, 3.0])
    before = (controller.velocity.copy(), controller.stiffness.copy())
    with pytest.raises(NonFiniteForceError, match=r"^force\[1, 0\] is nan"):
        controller.step([float("nan"), 0.0, 0.0])
    assert np.array_equal(controller.velocity, before[0])
    assert np.array_equal(controller.stiffness, before[1])


def test_stability_report_of_the_paper_end_effector() -> None:
    report = stability_report("adaptive", EE, axes=1, dt=0.002)
    assert report.b_min[0] == 120.0
    assert report.k_min[0] == pytest.approx(90.0)
    assert report.gamma_bound[0] == pytest.approx(2 * 120 * 90 / (20 * 300))
    # the paper's own collision parameters are overdamped: zeta > 1 is stable
    assert report.zeta_max[0] == pytest.approx(150 / (2 * np.sqrt(20 * 90)))
    assert report.zeta_max[0] > 1
    assert report.omega_n_max[0] == pytest.approx(np.sqrt(15.0))


def test_simulate_with_a_law_name_needs_dt_and_params() -> None:
    with pytest.raises(ParameterError, match=r"^dt and params are required with a law name$"):
        simulate("fixed", np.zeros((3, 1)), 0.001)
    controller = make("fixed", EE, axes=1)
    with pytest.raises(ParameterError, match=r"^pass either a controller or law/params/dt"):
        simulate(controller, np.zeros((3, 1)), params=EE)


@pytest.mark.parametrize(
    ("law", "overrides", "message"),
    [
        (
            "adaptive",
            {"m": 1e-300},
            "m = 1e-300, b_d = 150, k_d = 300 on axis 0: dt*(b_d + k_d)/m = 9e+299 at dt = 0.002 s "
            "must be <= 1e+06, or the discretised filter loses its precision and overflows",
        ),
        (
            "fixed",
            {"k_d": 1e300},
            "m = 20, b_d = 150, k_d = 1e+300 on axis 0: dt*(b_d + k_d)/m = 1e+296 at dt = "
            "0.002 s must be <= 1e+06, or the discretised filter loses its precision and overflows",
        ),
        (
            "adaptive",
            {"m": 1e300},
            "m = 1e+300, b_min = 120, k_min = 90 on axis 0: the slowest mode decays by 1.2e-301 "
            "per tick of 0.002 s, less than 1e-12, so in float64 the filter would never return "
            "to rest",
        ),
        (
            "fixed",
            {"b_d": 1e-300},
            "m = 20, b_min = 1e-300, k_min = 300 on axis 0: the slowest mode decays by 5e-305 "
            "per tick of 0.002 s, less than 1e-12, so in float64 the filter would never return "
            "to rest",
        ),
        (
            "fixed",
            {"m": 1e-200, "b_d": 1e-200, "k_d": 1e-200},
            "m = 1e-200, b_min = 1e-200, k_min = 1e-200 on axis 0: the damping ratio "
            "b/(2*sqrt(m*k)) = inf must be finite",
        ),
        (
            "adaptive",
            {"hold_s": 1e300},
            "hold_s = 1e+300 s must be at most 2**53 ticks of dt = 0.002 s (1.80144e+13 s)",
        ),
    ],
)
def test_parameters_whose_discrete_filter_is_not_finite_or_stable_are_refused(
    law: str, overrides: dict, message: str
) -> None:
    with pytest.raises(ParameterError) as err:
        make(law, {"preset": EE, **overrides}, axes=1, dt=0.002)
    assert str(err.value) == message


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # overflowing bounds of refused sets
@pytest.mark.parametrize("law", ["fixed", "adaptive"])
@pytest.mark.parametrize("integrator", ["zoh", "euler"])
def test_every_accepted_mass_damping_and_stiffness_gives_finite_results(
    law: str, integrator: str
) -> None:
    force = np.zeros((40, 1))
    force[5:25, 0] = 5.0
    exponents = (-300, -30, -12, -6, -2, 0, 2, 6, 12, 30, 300)
    accepted = 0
    for m, b, k in itertools.product((10.0**e for e in exponents), repeat=3):
        values = {"m": m, "b_d": b, "k_d": k, "beta": 0.2 * b, "integrator": integrator}
        try:
            result = simulate(law, force, 0.002, {"preset": "adaptive", **values})
        except ParameterError:
            continue
        accepted += 1
        for name in ("offset", "velocity", "damping", "stiffness", "zeta"):
            assert np.isfinite(getattr(result, name)).all(), (name, m, b, k)
    assert accepted > 20
