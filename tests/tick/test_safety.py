"""The safety clamp: every guarantee on every tick for arbitrary inputs, and each flag by hand."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.errors import ParameterError
from hilrig.robot import AUBO_I5_LIMITS, JointLimits, RobotModel
from hilrig.tick.safety import Clamp, SafetyClamp, SafetyConfig, axis_reach_m

HOME = np.array(HOME_Q_RAD)
DT = 0.001
# Guarantees hold to float64 rounding: velocities and accelerations are differences of positions.
REL = 1e-9
WIDE_BOX = SafetyConfig(workspace_min_m=(-3.0, -3.0, -3.0), workspace_max_m=(3.0, 3.0, 3.0))
SLOW = JointLimits(
    position_min_rad=AUBO_I5_LIMITS.position_min_rad,
    position_max_rad=AUBO_I5_LIMITS.position_max_rad,
    velocity_max_rad_s=(0.5,) * 6,
    acceleration_max_rad_s2=AUBO_I5_LIMITS.acceleration_max_rad_s2,
)


MODEL = RobotModel()


def run(
    clamp: SafetyClamp, commands: list[NDArray[np.float64] | None]
) -> tuple[NDArray[np.float64], list[int]]:
    """Feed targets (None: hold) one per tick; the commanded joints (N, 6) and flags per tick."""
    out = np.empty(6)
    q, flags = [], []
    for target in commands:
        flags.append(clamp.hold(out) if target is None else clamp.clamp(target, out))
        q.append(out.copy())
    return np.array(q).reshape(-1, 6), flags


def assert_guarantees(
    config: SafetyConfig, q0: NDArray[np.float64], q: NDArray[np.float64]
) -> None:
    """Every guarantee of the module docstring on every tick of the commanded sequence q."""
    lo, hi = config.lower_rad(), config.upper_rad()
    v_max = np.array(config.limits.velocity_max_rad_s)
    a_max = np.array(config.limits.acceleration_max_rad_s2)
    dt = config.dt_s
    assert np.isfinite(q).all()
    assert (q >= lo).all() and (q <= hi).all()
    qd = np.diff(np.vstack([q0, q]), axis=0) / dt
    assert (np.abs(qd) <= v_max * (1 + REL)).all()
    qdd = np.diff(np.vstack([np.zeros(6), qd]), axis=0) / dt  # the clamp starts at rest
    assert (np.abs(qdd) <= a_max * (1 + REL)).all()
    braking_rad = qd * qd / (2 * a_max)
    toward_hi = qd > 0
    assert (braking_rad[toward_hi] <= (hi - q)[toward_hi] + 1e-12).all()
    assert (braking_rad[~toward_hi] <= (q - lo)[~toward_hi] + 1e-12).all()
    box_min, box_max = np.array(config.workspace_min_m), np.array(config.workspace_max_m)
    for row in q:
        tcp = MODEL.fk(row)[:3, 3]
        assert (tcp >= box_min - 1e-12).all() and (tcp <= box_max + 1e-12).all(), tcp


# --- arbitrary inputs (hypothesis) ------------------------------------------------------------

LIMIT_LO = np.array(AUBO_I5_LIMITS.position_min_rad) + 0.05
LIMIT_HI = np.array(AUBO_I5_LIMITS.position_max_rad) - 0.05
wild = st.one_of(
    st.floats(-10.0, 10.0),
    st.sampled_from([math.nan, math.inf, -math.inf, 1e9, -1e9, 1e300, -1e300, 0.0]),
)
joint_targets = st.lists(wild, min_size=6, max_size=6).map(np.array)
Segment = tuple[str, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]
six_floats = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6).map(np.array)
# A segment of the command sequence: a fixed target, a target moving at up to 5 rad/s from an
# offset to the start, or a hold.
segments = st.tuples(
    st.sampled_from(["target", "moving", "hold"]),
    joint_targets,
    six_floats,
    six_floats,
    st.integers(1, 400),
)


def vec3(values: NDArray[np.float64]) -> tuple[float, float, float]:
    return float(values[0]), float(values[1]), float(values[2])


def near_limit_start(draw: st.DrawFn) -> NDArray[np.float64]:
    """Each joint anywhere in range, on a limit, or within a hair of one."""
    q0 = np.empty(6)
    for j in range(6):
        lo, hi = LIMIT_LO[j], LIMIT_HI[j]
        q0[j] = draw(
            st.one_of(
                st.floats(lo, hi),
                st.sampled_from([lo, hi, lo + 1e-9, hi - 1e-9, np.nextafter(hi, -np.inf)]),
            )
        )
    return q0


@st.composite
def scenarios(draw: st.DrawFn) -> tuple[SafetyConfig, NDArray[np.float64], list[Segment]]:
    """Random limits and tick; a start home-ish in a tight random box or near the joint limits."""
    limits = JointLimits(
        position_min_rad=AUBO_I5_LIMITS.position_min_rad,
        position_max_rad=AUBO_I5_LIMITS.position_max_rad,
        velocity_max_rad_s=draw(st.tuples(*[st.floats(0.2, 3.14)] * 6)),
        acceleration_max_rad_s2=draw(st.tuples(*[st.floats(0.5, 20.0)] * 6)),
    )
    dt_s = draw(st.sampled_from([0.001, 0.002]))
    if draw(st.booleans()):
        q0 = HOME + draw(st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6).map(np.array))
        tcp = MODEL.fk(q0)[:3, 3]
        below = np.array(draw(st.lists(st.floats(0.0, 0.2), min_size=3, max_size=3)))
        above = np.array(draw(st.lists(st.floats(1e-3, 0.2), min_size=3, max_size=3)))
        box_min, box_max = vec3(tcp - below), vec3(tcp + above)
    else:
        q0 = near_limit_start(draw)
        box_min, box_max = WIDE_BOX.workspace_min_m, WIDE_BOX.workspace_max_m
    config = SafetyConfig(
        limits=limits, workspace_min_m=box_min, workspace_max_m=box_max, dt_s=dt_s
    )
    commands = draw(st.lists(segments, min_size=1, max_size=8))
    return config, q0, commands


def expand(q0: NDArray[np.float64], plan: list[Segment]) -> list[NDArray[np.float64] | None]:
    commands: list[NDArray[np.float64] | None] = []
    for kind, target, offset, rate, count in plan:
        if kind == "hold":
            commands += [None] * count
        elif kind == "target":
            commands += [target] * count
        else:
            commands += [q0 + offset + 5.0 * rate * DT * n for n in range(count)]
    return commands


@settings(max_examples=400, deadline=None)
@given(scenario=scenarios())
def test_every_guarantee_holds_on_every_tick_for_arbitrary_targets(
    scenario: tuple[SafetyConfig, NDArray[np.float64], list[Segment]],
) -> None:
    config, q0, plan = scenario
    clamp = SafetyClamp(config, MODEL, q0)
    q, _ = run(clamp, expand(q0, plan))
    assert_guarantees(config, q0, q)


@settings(max_examples=60, deadline=None)
@given(signs=st.lists(st.lists(st.sampled_from([-1e9, 1e9]), min_size=6, max_size=6), min_size=1))
def test_bang_bang_targets_keep_every_guarantee(signs: list[list[float]]) -> None:
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    q, _ = run(clamp, [np.array(s) for s in signs for _ in range(37)])
    assert_guarantees(SafetyConfig(), HOME, q)


# --- each flag by hand ------------------------------------------------------------------------


def minimum_jerk(
    start: NDArray[np.float64], end: NDArray[np.float64], ticks: int
) -> list[NDArray[np.float64]]:
    tau = np.arange(1, ticks + 1) / ticks
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    return [start + (end - start) * x for x in s]


def test_a_smooth_target_within_every_limit_is_sent_exactly() -> None:
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    targets = minimum_jerk(HOME, HOME + np.array([0.05, -0.04, 0.03, 0.1, -0.1, 0.2]), 2000)
    q, flags = run(clamp, list(targets))
    assert flags == [0] * len(targets)
    assert np.array_equal(q, np.array(targets))


def test_a_jump_is_followed_at_the_acceleration_limit_without_overshoot() -> None:
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    target = HOME + np.array([0, 0, 0, 0, 0, 0.3])  # joint 6 turns the flange in place
    q, flags = run(clamp, [target] * 1000)
    assert flags[0] == Clamp.ACCELERATION
    assert q[0, 5] - HOME[5] == pytest.approx(3.0 * DT * DT)  # one tick at a_max from rest
    assert (np.diff(q[:, 5]) >= 0).all() and (q[:, 5] <= target[5]).all()  # no overshoot
    arrived = int(np.argmax(q[:, 5] == target[5]))
    # the time-optimal rest-to-rest move takes 2*sqrt(d/a) = 0.632 s
    assert 632 <= arrived <= 660
    assert flags[arrived + 1 :] == [0] * (len(flags) - arrived - 1)
    assert_guarantees(SafetyConfig(), HOME, q)


def test_position_flag_when_the_target_is_beyond_a_limit() -> None:
    hi = WIDE_BOX.upper_rad()[5]
    q0 = HOME.copy()
    q0[5] = hi - 0.2
    clamp = SafetyClamp(WIDE_BOX, MODEL, q0)
    target = q0.copy()
    target[5] = hi + 1.0
    q, flags = run(clamp, [target] * 1500)
    assert all(f & Clamp.POSITION for f in flags)
    assert q[:, 5].max() == hi  # reached, never passed
    assert_guarantees(WIDE_BOX, q0, q)


def test_position_flag_when_braking_for_a_limit_bounds_the_step() -> None:
    config = SafetyConfig(limits=SLOW, workspace_min_m=(-3, -3, -3), workspace_max_m=(3, 3, 3))
    hi = config.upper_rad()[5]
    q0 = HOME.copy()
    q0[5] = hi - 0.3
    clamp = SafetyClamp(config, MODEL, q0)
    # a target moving through the limit at 0.4 rad/s: only the limit's braking curve stops it
    targets = [q0 + np.array([0, 0, 0, 0, 0, 0.4 * DT * (n + 1)]) for n in range(1500)]
    q, flags = run(clamp, targets)
    assert any(f == Clamp.POSITION for f in flags)
    assert q[:, 5].max() <= hi
    assert_guarantees(config, q0, q)


def test_velocity_flag_caps_the_speed() -> None:
    config = SafetyConfig(limits=SLOW)
    clamp = SafetyClamp(config, MODEL, HOME)
    q, flags = run(clamp, [HOME + np.array([0, 0, 0, 0, 0, 2.0])] * 3000)
    speed = np.abs(np.diff(q[:, 5])) / DT
    assert any(f == Clamp.VELOCITY for f in flags)
    assert speed.max() == pytest.approx(0.5, rel=1e-9)
    assert_guarantees(config, HOME, q)


def test_workspace_flag_brakes_before_the_flange_leaves_the_box() -> None:
    tcp = MODEL.fk(HOME)[:3, 3]
    config = SafetyConfig(
        workspace_min_m=(0.15, -0.6, float(tcp[2]) - 0.02), workspace_max_m=(0.85, 0.6, 0.9)
    )
    low_pose = MODEL.fk(HOME)
    low_pose[2, 3] -= 0.15
    below = MODEL.ik(low_pose, HOME).q_rad
    clamp = SafetyClamp(config, MODEL, HOME)
    q, flags = run(clamp, [below] * 2000)
    assert Clamp.WORKSPACE in [Clamp(f) for f in flags]
    heights = np.array([MODEL.fk(row)[2, 3] for row in q])
    assert heights.min() >= config.workspace_min_m[2]
    assert heights.min() < config.workspace_min_m[2] + 0.005  # it does get close to the floor
    assert_guarantees(config, HOME, q)


def moving_clamp(config: SafetyConfig = WIDE_BOX) -> SafetyClamp:
    """A clamp whose joints all move, at different speeds, after 400 ticks toward a far target."""
    clamp = SafetyClamp(config, MODEL, HOME)
    run(clamp, [HOME + np.array([0.4, -0.3, 0.5, 0.8, -0.8, 1.5])] * 400)
    assert (np.abs(clamp.qd_rad_s) > 0.3).all()
    return clamp


def test_a_non_finite_target_is_a_hold() -> None:
    held, twin = moving_clamp(), moving_clamp()
    out, twin_out = np.empty(6), np.empty(6)
    for bad in (math.nan, math.inf, -math.inf):
        target = HOME.copy()
        target[2] = bad
        assert held.clamp(target, out) == Clamp.NON_FINITE | Clamp.HOLDING
        assert twin.hold(twin_out) == Clamp.HOLDING
        assert np.array_equal(out, twin_out)


def test_hold_reaches_standstill_within_v_over_a_plus_one_tick() -> None:
    clamp = moving_clamp()
    q0 = clamp.q_rad.copy()
    speed = np.abs(clamp.qd_rad_s)
    a_max = np.array(AUBO_I5_LIMITS.acceleration_max_rad_s2)
    allowed_ticks = math.floor(float(np.max(speed / a_max)) / DT) + 1
    out = np.empty(6)
    qd = [clamp.qd_rad_s.copy()]
    for _ in range(allowed_ticks + 50):
        assert clamp.hold(out) == Clamp.HOLDING
        qd.append(clamp.qd_rad_s.copy())
    qd_all = np.array(qd)
    still = int(np.argmax(np.all(qd_all == 0.0, axis=1)))
    assert 0 < still <= allowed_ticks
    assert (qd_all[still:] == 0.0).all()
    assert (np.abs(np.diff(qd_all, axis=0)) / DT <= a_max * (1 + REL)).all()
    assert (qd_all * qd_all[0] >= 0).all()  # slows down, never reverses
    assert np.array_equal(clamp.q_rad, out) and not np.array_equal(out, q0)


def test_tracking_resumes_after_a_hold_and_settles_on_the_target() -> None:
    clamp = moving_clamp()
    q0, qd0 = clamp.q_rad.copy(), clamp.qd_rad_s.copy()
    commands: list[NDArray[np.float64] | None] = [None] * 100 + [HOME] * 3000
    q, flags = run(clamp, commands)
    assert flags[:100] == [Clamp.HOLDING] * 100
    assert np.array_equal(q[-1], HOME) and flags[-1] == 0 and (clamp.qd_rad_s == 0).all()
    qd = np.vstack([qd0, np.diff(np.vstack([q0, q]), axis=0) / DT])
    assert (np.abs(np.diff(qd, axis=0)) / DT <= 3.0 * (1 + REL)).all()


# --- protective stop --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("force_n", "torque_nm", "stop"),
    [
        ((0.0, 0.0, 0.0), (0.0,) * 6, False),
        ((36.0, 48.0, 0.0), (0.0,) * 6, False),  # norm exactly 60 N
        ((36.0, 48.0, 0.1), (0.0,) * 6, True),
        ((0.0, 0.0, -61.0), (0.0,) * 6, True),
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, -25.0, 0.0), False),
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, -25.01), True),
        ((0.0, 0.0, 0.0), (25.5, 0.0, 0.0, 0.0, 0.0, 0.0), True),
        ((math.nan, 0.0, 0.0), (0.0,) * 6, True),
        ((0.0, 0.0, 0.0), (0.0, 0.0, math.inf, 0.0, 0.0, 0.0), True),
    ],
)
def test_stop_required_at_the_protective_limits(
    force_n: tuple[float, ...], torque_nm: tuple[float, ...], stop: bool
) -> None:
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    assert clamp.stop_required(np.array(force_n), np.array(torque_nm)) is stop


# --- construction and interface ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("q0", "config", "message"),
    [
        (HOME + np.array([0, 0, 0, 0, 0, 3.01]), SafetyConfig(), "joint 6"),
        (np.array([0, 0, 0, 0, 0, math.nan]), SafetyConfig(), "finite"),
        (np.zeros(5), SafetyConfig(), "6 finite"),
        (HOME, SafetyConfig(workspace_min_m=(0.6, -0.6, 0.05)), "outside the workspace"),
    ],
)
def test_an_unsafe_start_is_refused(
    q0: NDArray[np.float64], config: SafetyConfig, message: str
) -> None:
    with pytest.raises(ParameterError, match=message):
        SafetyClamp(config, MODEL, q0)


@pytest.mark.parametrize(
    "options",
    [
        {"workspace_min_m": (0.9, -0.6, 0.05)},
        {"workspace_max_m": (0.85, 0.6, math.nan)},
        {"workspace_min_m": (0.1, 0.2)},
        {"position_margin_rad": 3.1},
        {"position_margin_rad": -0.1},
        {"protective_force_n": 0.0},
        {"protective_torque_nm": math.inf},
        {"dt_s": -0.001},
    ],
)
def test_bad_config_is_refused_in_one_line(options: dict[str, object]) -> None:
    with pytest.raises(ParameterError) as error:
        SafetyConfig(**options)  # type: ignore[arg-type]
    assert "\n" not in str(error.value)


def test_state_accessors_are_read_only_views_of_the_last_command() -> None:
    clamp = moving_clamp()
    out = np.empty(6)
    previous = clamp.q_rad.copy()
    clamp.hold(out)
    assert np.array_equal(clamp.q_rad, out)
    assert np.allclose(clamp.qd_rad_s, (out - previous) / DT, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="read-only"):
        clamp.q_rad[0] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        clamp.qd_rad_s[0] = 0.0


def test_the_output_may_be_the_target_array() -> None:
    clamp, twin = SafetyClamp(SafetyConfig(), MODEL, HOME), SafetyClamp(SafetyConfig(), MODEL, HOME)
    twin_out = np.empty(6)
    for _ in range(50):
        buffer = HOME + 0.2
        flags = clamp.clamp(buffer, buffer)
        assert flags == twin.clamp(HOME + 0.2, twin_out)
        assert np.array_equal(buffer, twin_out)


@pytest.mark.parametrize(
    ("target", "out"),
    [(np.zeros(5), np.empty(6)), (np.zeros(6), np.empty(7)), (np.zeros(6), np.empty(6, "f4"))],
)
def test_wrong_shapes_or_dtypes_are_refused(
    target: NDArray[np.float64], out: NDArray[np.float64]
) -> None:
    clamp = SafetyClamp(SafetyConfig(), MODEL, HOME)
    with pytest.raises(ParameterError, match="shape"):
        clamp.clamp(target, out)


def test_axis_reach_bounds_the_jacobian_at_any_configuration() -> None:
    """The premise of the workspace argument: |column j of the linear Jacobian| <= R_j."""
    reach = axis_reach_m(MODEL)
    assert reach == pytest.approx([1.102, 0.9805, 0.5725, 0.1965, 0.094, 0.0])
    rng = np.random.default_rng(7)
    for q in rng.uniform(-3.05, 3.05, size=(2000, 6)):
        column_norms = np.linalg.norm(MODEL.jacobian(q)[:3], axis=0)
        assert (column_norms <= reach + 1e-12).all()


def test_axis_reach_counts_the_tool() -> None:
    tool = np.eye(4)
    tool[:3, 3] = (0.0, 0.03, 0.04)  # 5 cm
    reach = axis_reach_m(RobotModel(tcp_in_flange=tool))
    assert reach == pytest.approx(np.array([1.102, 0.9805, 0.5725, 0.1965, 0.094, 0.0]) + 0.05)
