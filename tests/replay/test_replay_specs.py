"""--controller, --set and --sweep: typed specs, run names, grids, and one-line errors."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hilrig.control import Law, preset
from hilrig.replay import ReplayError, parse_specs
from hilrig.replay import specs as specs_module
from hilrig.replay.specs import MAX_RUNS


def test_no_controller_means_the_three_laws_with_the_loops_presets() -> None:
    specs = parse_specs()
    assert [(s.name, s.law) for s in specs] == [
        ("fixed", Law.FIXED),
        ("variable-stiffness", Law.VARIABLE_STIFFNESS),
        ("adaptive", Law.ADAPTIVE),
    ]
    assert all(s.cartesian == preset("adaptive") for s in specs)
    assert all(s.joint == preset("adaptive-joint") for s in specs)


def test_a_setting_renames_a_law_named_run_and_applies_to_both_groups() -> None:
    (spec,) = parse_specs(["adaptive"], ["adaptive.a1=10", "adaptive.state_machine=false"])
    assert spec.name == "adaptive.a1=10.state_machine=false"
    assert spec.cartesian.a1 == spec.joint.a1 == 10.0
    assert spec.cartesian.state_machine is False and spec.joint.state_machine is False
    assert spec.overrides == {"a1": 10.0, "state_machine": False}


def test_a_named_controller_keeps_its_name_and_groups_are_set_apart() -> None:
    (spec,) = parse_specs(
        ["soft=adaptive"], ["soft.cartesian.k_d=100,200,300", "soft.joint.chi=abs"]
    )
    assert spec.name == "soft" and spec.controller == "soft"
    assert spec.cartesian.k_d == (100.0, 200.0, 300.0) and spec.joint.k_d == 150.0
    assert spec.joint.chi == "abs" and spec.cartesian.chi == "square"


def test_presets_apply_before_the_other_settings_whatever_the_order() -> None:
    (spec,) = parse_specs(
        ["p=adaptive"], ["p.cartesian.a1=7", "p.cartesian.preset=paper-end-effector"]
    )
    assert spec.cartesian == preset("paper-end-effector").with_(a1=7.0)


def test_sweeps_of_one_controller_run_as_a_grid_with_named_points() -> None:
    specs = parse_specs(
        ["adaptive", "fixed"],
        sweeps=["adaptive.a1=5:40:8", "adaptive.joint.chi=square,abs"],
    )
    names = [s.name for s in specs]
    assert len(specs) == 8 * 2 + 1
    assert names[:3] == [
        "adaptive.a1=5.joint.chi=square",
        "adaptive.a1=5.joint.chi=abs",
        "adaptive.a1=10.joint.chi=square",
    ]
    assert names[-1] == "fixed"
    a1 = sorted({s.cartesian.a1 for s in specs[:-1]})
    assert a1 == [5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0]


def test_sweep_values_are_rounded_to_what_their_names_say() -> None:
    specs = parse_specs(["adaptive"], sweeps=["adaptive.a2=0.1:0.5:5"])
    assert [s.name for s in specs][2] == "adaptive.a2=0.3"
    assert specs[2].cartesian.a2 == 0.3


@given(st.lists(st.integers(1, 4), min_size=1, max_size=3))
def test_a_grid_has_the_product_of_the_counts_and_unique_names(counts: list[int]) -> None:
    params = ["a1", "beta", "delta"]
    sweeps = [
        f"adaptive.{p}=1:{2 if n > 1 else 1}:{n}" for p, n in zip(params, counts, strict=False)
    ]
    specs = parse_specs(["adaptive"], sweeps=sweeps)
    expected = 1
    for n in counts:
        expected *= n
    assert len(specs) == expected
    assert len({s.name for s in specs}) == expected


@pytest.mark.parametrize(
    ("controllers", "sets", "sweeps", "message"),
    [
        (
            ["pid"],
            [],
            [],
            "--controller pid: law 'pid' is not one of: fixed, variable-stiffness, adaptive",
        ),
        (
            ["my run=fixed"],
            [],
            [],
            "--controller my run=fixed: name 'my run' must be letters, digits, '_' or '-'",
        ),
        (["fixed", "fixed"], [], [], "--controller fixed: controller 'fixed' is declared twice"),
        (["fixed"], ["fixed.k_d"], [], "--set fixed.k_d: expected NAME.PARAM=VALUE"),
        (["fixed"], ["soft.k_d=1"], [], "--set soft.k_d=1: no controller 'soft' (declared: fixed)"),
        (
            ["fixed"],
            ["fixed.kd=1"],
            [],
            "--set fixed.kd=1: unknown parameter 'kd'; known: preset, "
            "m, b_d, k_d, a1, a2, beta, delta, b_min, gamma, chi, beta_reading, integrator, "
            "state_machine, rate_guard, debounce_s, release_s, hold_s, settle_tol",
        ),
        (
            ["fixed"],
            ["fixed.arm.k_d=1"],
            [],
            "--set fixed.arm.k_d=1: group 'arm' is not one of: cartesian, joint",
        ),
        (
            ["fixed"],
            ["fixed.preset=paper-joint"],
            [],
            "--set fixed.preset=paper-joint: a preset "
            "belongs to one group: NAME.cartesian.preset=... or NAME.joint.preset=...",
        ),
        (
            ["fixed"],
            ["fixed.k_d=1,2,3"],
            [],
            "--set fixed.k_d=1,2,3: per-axis values need a group (NAME.cartesian.k_d=...)",
        ),
        (
            ["fixed"],
            ["fixed.joint.k_d=1,2,3"],
            [],
            "--set fixed.joint.k_d=1,2,3: the joint group has 6 axes, got 3 values",
        ),
        (
            ["fixed"],
            ["fixed.cartesian.k_d=1,x,3"],
            [],
            "--set fixed.cartesian.k_d=1,x,3: 'x' is not a number",
        ),
        (
            ["fixed"],
            ["fixed.k_d=stiff"],
            [],
            "run fixed.k_d=stiff: k_d=stiff: k_d takes a number, not 'stiff'",
        ),
        (
            ["fixed"],
            ["fixed.rate_guard=1"],
            [],
            "run fixed.rate_guard=1: rate_guard=1: rate_guard takes true or false, not '1'",
        ),
        (
            ["fixed"],
            ["fixed.chi=cube"],
            [],
            "run fixed.chi=cube: chi=cube: chi = 'cube' is not one of: square, abs, group-square",
        ),
        (
            ["fixed"],
            ["fixed.joint.preset=soft"],
            [],
            "run fixed.joint.preset=soft: "
            "joint.preset=soft: unknown preset 'soft'; known: adaptive, adaptive-joint, "
            "paper-end-effector, paper-joint",
        ),
        (["fixed"], [], ["fixed.k_d=1:2"], "--sweep fixed.k_d=1:2: expected START:STOP:COUNT"),
        (
            ["fixed"],
            [],
            ["fixed.k_d=1:2:x"],
            "--sweep fixed.k_d=1:2:x: COUNT 'x' is not a whole number",
        ),
        (["fixed"], [], ["fixed.k_d=1:2:0"], "--sweep fixed.k_d=1:2:0: COUNT must be >= 1"),
        (
            ["fixed"],
            [],
            ["fixed.k_d=1:nan:2"],
            "--sweep fixed.k_d=1:nan:2: START and STOP must be finite",
        ),
        (["fixed"], [], ["fixed.k_d=1,1"], "--sweep fixed.k_d=1,1: values repeat"),
        (["a=fixed", "b=fixed"], ["a.k_d=1"], [], None),
    ],
)
def test_malformed_specs_are_refused_in_one_line(
    controllers: list[str], sets: list[str], sweeps: list[str], message: str | None
) -> None:
    if message is None:  # the last case is valid: two named controllers of one law
        assert [s.name for s in parse_specs(controllers, sets, sweeps)] == ["a", "b"]
        return
    with pytest.raises(ReplayError) as caught:
        parse_specs(controllers, sets, sweeps)
    assert str(caught.value) == message


def test_a_sweep_value_written_twice_is_refused() -> None:
    with pytest.raises(ReplayError, match=r"^--sweep fixed\.k_d=1,1\.0: values repeat$"):
        parse_specs(["fixed"], sweeps=["fixed.k_d=1,1.0"])


def test_count_1_is_one_value_only_when_start_equals_stop() -> None:
    (spec,) = parse_specs(["fixed"], sweeps=["fixed.k_d=250:250:1"])
    assert spec.name == "fixed.k_d=250" and spec.cartesian.k_d == 250.0
    with pytest.raises(ReplayError) as caught:
        parse_specs(["fixed"], sweeps=["fixed.k_d=200:400:1"])
    assert str(caught.value) == (
        "--sweep fixed.k_d=200:400:1: COUNT 1 cannot include both START and STOP; "
        "use COUNT >= 2, or START = STOP for one value"
    )


def test_a_grid_over_the_run_limit_is_refused_before_anything_is_expanded(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def expanded(*args: object) -> None:
        raise AssertionError("a sweep was expanded")

    monkeypatch.setattr(specs_module, "_sweep", expanded)
    cases = [
        (
            ["adaptive"],
            ["adaptive.a1=1:40:10000", "adaptive.beta=1:29:10000"],
            "--sweep: 100000000 runs (adaptive: 10000 x 10000), more than the limit of 10000; "
            "sweep fewer values",
        ),
        (
            ["soft=adaptive", "fixed"],
            ["soft.a1=1:40:100", "soft.joint.chi=square,abs", "fixed.k_d=1:2:10000"],
            "--sweep: 10200 runs (soft: 100 x 2; fixed: 10000), more than the limit of 10000; "
            "sweep fewer values",
        ),
    ]
    for controllers, sweeps, message in cases:
        with pytest.raises(ReplayError) as caught:
            parse_specs(controllers, sweeps=sweeps)
        assert str(caught.value) == message


def test_the_run_limit_counts_every_controller() -> None:
    assert MAX_RUNS == 10_000
    specs = parse_specs(["fixed"], sweeps=[f"fixed.k_d=1:2:{MAX_RUNS}"])
    assert len(specs) == MAX_RUNS
    with pytest.raises(ReplayError, match=r"^--sweep: 10001 runs \(fixed: 10000\), more than"):
        parse_specs(["fixed", "adaptive"], sweeps=[f"fixed.k_d=1:2:{MAX_RUNS}"])
