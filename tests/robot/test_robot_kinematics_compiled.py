"""The compiled kernels of hilrig.robot.kinematics against RobotModel's FK, Jacobian and IK."""

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numba import njit
from numba.core.runtime import _nrt_python, rtsys
from numpy.typing import NDArray

from hilrig.robot import (
    AUBO_I5_LIMITS,
    IK_ERRORS,
    CompiledChain,
    JointLimits,
    RobotModel,
    RobotModelError,
    aubo_i5_urdf,
    fk_into,
    ik_into,
    ik_work,
    jacobian_into,
    log3_into,
    warm_up,
)

F64 = NDArray[np.float64]
LOOP_OPTIONS = {"max_iterations": 2, "tol_position_m": 1e-8, "tol_rotation_rad": 1e-8}
TOOL = np.array(
    [[0.0, -1.0, 0.0, 0.01], [1.0, 0.0, 0.0, -0.02], [0.0, 0.0, 1.0, 0.15], [0, 0, 0, 1]]
)

joint_angle = st.floats(-3.05, 3.05, allow_nan=False)
joint_vectors = st.lists(joint_angle, min_size=6, max_size=6).map(np.array)
# Start offsets of 0 or at least 1 mrad: an error equal to a tolerance to the last bit (as a
# 1e-6 rad nudge gives) may converge in one implementation and not the other.
nudge = st.floats(-0.3, 0.3).filter(lambda x: x == 0.0 or abs(x) >= 1e-3)
nudges = st.lists(nudge, min_size=6, max_size=6).map(np.array)


@pytest.fixture(scope="module", params=["flange", "tool"])
def pair(request: pytest.FixtureRequest) -> tuple[RobotModel, CompiledChain]:
    model = RobotModel(tcp_in_flange=TOOL if request.param == "tool" else None)
    chain = CompiledChain.from_model(model)
    warm_up(chain)
    return model, chain


def rotation(axis: F64, angle_rad: float) -> F64:
    matrix: F64 = pin.exp3(axis / np.linalg.norm(axis) * angle_rad)
    return matrix


def assert_same_ik(
    model: RobotModel, chain: CompiledChain, goal: F64, q0: F64, **options: float
) -> None:
    expected = model.ik(goal, q0, **options)  # type: ignore[arg-type]
    got = chain.ik(goal, q0, **options)  # type: ignore[arg-type]
    assert (got.converged, got.iterations) == (expected.converged, expected.iterations)
    np.testing.assert_allclose(got.q_rad, expected.q_rad, rtol=0, atol=1e-12)
    assert got.position_error_m == pytest.approx(expected.position_error_m, rel=0, abs=1e-12)
    assert got.rotation_error_rad == pytest.approx(expected.rotation_error_rad, rel=0, abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(q=joint_vectors)
def test_fk_and_jacobian_match_the_model(pair: tuple[RobotModel, CompiledChain], q: F64) -> None:
    model, chain = pair
    pose, jac = np.empty((4, 4)), np.empty((6, 6))
    fk_into(chain.frames, chain.axes, q, pose)
    np.testing.assert_allclose(pose, model.fk(q), rtol=0, atol=1e-12)
    pose[:] = 0.0
    jacobian_into(chain.frames, chain.axes, q, pose, jac)
    np.testing.assert_allclose(jac, model.jacobian(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(pose, model.fk(q), rtol=0, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(q_goal=joint_vectors, nudge=nudges, loop_options=st.booleans())
def test_ik_matches_the_model_from_a_nearby_start(
    pair: tuple[RobotModel, CompiledChain], q_goal: F64, nudge: F64, loop_options: bool
) -> None:
    model, chain = pair
    # Near a singularity both solvers' rounding (cond(J)^2 * eps) exceeds 1e-12: not compared.
    assume(np.linalg.cond(model.jacobian(q_goal)) < 100.0)
    q0 = np.clip(q_goal + nudge, -3.05, 3.05)
    options = LOOP_OPTIONS if loop_options else {}
    assert_same_ik(model, chain, model.fk(q_goal), q0, **options)


@pytest.mark.parametrize("options", [LOOP_OPTIONS, {}], ids=["loop", "defaults"])
def test_ik_matches_when_iterates_are_clipped(options: dict[str, float]) -> None:
    tight = JointLimits(
        position_min_rad=(-0.1,) * 6,
        position_max_rad=(0.1,) * 6,
        velocity_max_rad_s=AUBO_I5_LIMITS.velocity_max_rad_s,
        acceleration_max_rad_s2=AUBO_I5_LIMITS.acceleration_max_rad_s2,
    )
    constrained = RobotModel(limits=tight)
    chain = CompiledChain.from_model(constrained)
    goal = RobotModel().fk(np.array([1.0, 0.5, -0.5, 0.5, 0.5, 0.5]))
    assert_same_ik(constrained, chain, goal, np.zeros(6), **options)
    # the packaged limits: a goal just beyond joint 1's and joint 6's limits
    model = RobotModel()
    beyond = np.array([3.2, 0.4, 1.1, 0.3, 0.9, -3.15])
    assert_same_ik(
        model, CompiledChain.from_model(model), model.fk(beyond), beyond * 0.9, **options
    )


@pytest.mark.parametrize("options", [LOOP_OPTIONS, {}], ids=["loop", "defaults"])
@pytest.mark.parametrize("below_pi", [1e-9, 1e-5, 1e-2])
def test_ik_matches_for_a_goal_turned_nearly_pi(
    pair: tuple[RobotModel, CompiledChain], options: dict[str, float], below_pi: float
) -> None:
    model, chain = pair
    q0 = np.array([0.4, -0.3, 1.2, 0.2, 0.8, 0.1])
    goal = model.fk(q0)
    goal[:3, :3] = rotation(np.array([0.3, -0.5, 0.8]), math.pi - below_pi) @ goal[:3, :3]
    assert_same_ik(model, chain, goal, q0, **options)


def test_unreachable_goal_reports_not_converged_with_errors() -> None:
    model = RobotModel()
    chain = CompiledChain.from_model(model)
    goal = np.eye(4)
    goal[:3, 3] = [2.0, 0.0, 0.5]
    q = np.array([0.0, 0.5, 1.0, 0.0, 1.0, 0.0])
    expected = model.ik(goal, q, max_iterations=30)
    work = ik_work()
    code = ik_into(chain.frames, chain.axes, chain.limits, goal, q, 30, 1e-6, 1e-6, 1e-4, 0.5, work)
    assert code == -31  # not converged after 30 steps
    assert work[IK_ERRORS, 0] == pytest.approx(expected.position_error_m, abs=1e-12)
    assert work[IK_ERRORS, 1] == pytest.approx(expected.rotation_error_rad, abs=1e-12)
    assert AUBO_I5_LIMITS.contains(q)


@settings(max_examples=100, deadline=None)
@given(
    axis=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array),
    angle=st.one_of(
        st.floats(0.0, 1e-4),  # near 0: the series
        st.floats(1e-4, math.pi - 1e-2),  # generic
        st.floats(math.pi - 1e-2, math.pi),  # near pi: the diagonal formula
    ),
)
def test_log3_matches_pinocchio(axis: F64, angle: float) -> None:
    assume(np.linalg.norm(axis) > 1e-3)
    matrix = rotation(axis, angle)
    out = np.empty(3)
    theta = log3_into(matrix, out)
    pin_theta = np.zeros((1, 1))
    np.testing.assert_allclose(out, pin.log3(matrix, pin_theta), rtol=0, atol=1e-12)
    assert theta == pytest.approx(pin_theta[0, 0], rel=0, abs=1e-12)  # pinocchio's acos angle


@pytest.mark.parametrize("matrix", [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1, -1])])
def test_log3_matches_pinocchio_at_0_and_pi_exactly(matrix: F64) -> None:
    out = np.empty(3)
    log3_into(matrix, out)
    np.testing.assert_allclose(out, pin.log3(matrix), rtol=0, atol=1e-12)


@njit
def _track(frames: F64, axes: F64, limits: F64, goals: F64, q: F64, out: F64) -> int:
    """A loop in numba: IK to each goal, then FK and the Jacobian there; sums the return codes."""
    pose, jac, work = np.empty((4, 4)), np.empty((6, 6)), np.zeros((20, 6))
    total = 0
    for k in range(goals.shape[0]):
        total += ik_into(frames, axes, limits, goals[k], q, 2, 1e-8, 1e-8, 1e-4, 0.5, work)
        fk_into(frames, axes, q, pose)
        jacobian_into(frames, axes, q, pose, jac)
        out[k] = pose[0, 3] + jac[0, 0]
    return total


def test_kernels_compose_in_an_outer_njit_loop_without_allocating() -> None:
    model = RobotModel()
    chain = CompiledChain.from_model(model)
    center = np.array([0.1, -0.5, 1.2, 0.3, 1.0, 0.2])
    ticks = np.arange(200) * 1e-3
    qs = center + 0.3 * np.sin(np.outer(ticks, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]))
    goals = np.array([model.fk(q) for q in qs])
    q, out = qs[0].copy(), np.empty(len(goals))
    args = (chain.frames, chain.axes, chain.limits)
    total = _track(*args, goals, q, out)
    assert 0 <= total <= 2 * len(goals)  # every tick converged in at most two steps
    np.testing.assert_allclose(q, qs[-1], atol=1e-8)
    expected = model.fk(q)[0, 3] + model.jacobian(q)[0, 0]
    assert out[-1] == pytest.approx(expected, abs=1e-12)
    try:
        _nrt_python.memsys_enable_stats()  # numba's allocation counters, off by default
        before = rtsys.get_allocation_stats().alloc
        _track(*args, goals[:1], q, out)
        one = rtsys.get_allocation_stats().alloc - before
        before = rtsys.get_allocation_stats().alloc
        _track(*args, goals, q, out)
        many = rtsys.get_allocation_stats().alloc - before
    except (AttributeError, RuntimeError):  # a numba without these counters
        pytest.skip("numba NRT allocation statistics are disabled")
    assert many == one  # the only allocations are per call (arguments, the work arrays)


def _urdf(old: str, new: str) -> str:
    text = aubo_i5_urdf()
    assert old in text
    return text.replace(old, new, 1)


def test_rx_ry_and_unaligned_axes_match_the_model() -> None:
    urdf = aubo_i5_urdf().replace('<axis xyz="0 0 1"/>', '<axis xyz="0 1 0"/>', 1)
    urdf = urdf.replace('<axis xyz="0 0 1"/>', '<axis xyz="1 0 0"/>', 1)
    urdf = urdf.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0.6 0.8"/>', 1)
    model = RobotModel(urdf, tcp_in_flange=TOOL)
    kinds = [joint.shortname() for joint in pin.buildModelFromXML(urdf).joints[1:4]]
    assert kinds == ["JointModelRY", "JointModelRX", "JointModelRevoluteUnaligned"]
    chain = CompiledChain.from_model(model)
    q = np.array([0.5, -0.3, 1.2, -0.7, 0.9, 2.0])
    np.testing.assert_allclose(chain.fk(q), model.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(chain.jacobian(q), model.jacobian(q), rtol=0, atol=1e-12)
    assert_same_ik(model, chain, model.fk(q + 0.05), q)


def test_a_prismatic_joint_is_refused() -> None:
    urdf = _urdf(
        '<joint name="wrist3_joint" type="revolute">',
        '<joint name="wrist3_joint" type="prismatic">',
    )
    with pytest.raises(
        RobotModelError,
        match=r"^CompiledChain: joint 'wrist3_joint' is JointModelPZ, not revolute$",
    ):
        CompiledChain.from_model(RobotModel(urdf))


def test_wrong_joint_vector_shape_is_refused() -> None:
    chain = CompiledChain.from_model(RobotModel())
    with pytest.raises(RobotModelError, match=r"CompiledChain.fk: q_rad must have shape \(6,\)"):
        chain.fk(np.zeros(7))
