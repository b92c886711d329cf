"""Forward kinematics and Jacobian of the packaged AUBO-i5 against an independent DH oracle."""

import math

import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

from hilrig.robot import AUBO_I5_LIMITS, RobotModel, RobotModelError, aubo_i5_urdf

# AUBO's public DH values (docs/rig.md, The robot model), modified (Craig) convention:
# alpha[i-1], a[i-1] (m), d[i] (m), theta offset[i] (rad)
DH_TABLE = (
    (0.0, 0.0, 0.122, math.pi),
    (-math.pi / 2, 0.0, 0.1215, -math.pi / 2),
    (math.pi, 0.408, 0.0, 0.0),
    (math.pi, 0.376, 0.0, -math.pi / 2),
    (-math.pi / 2, 0.0, 0.1025, 0.0),
    (math.pi / 2, 0.0, 0.094, 0.0),
)

POSES_RAD = (
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (0.5, -0.3, 1.2, -0.7, 0.9, 2.0),
    (-2.9, 1.4, -2.5, 3.0, -1.1, -3.0),
    (1.5707963, -1.5707963, 1.5707963, 0.0, -1.5707963, 0.3),
    (0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
)


def rot_x(angle: float) -> NDArray[np.float64]:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_z(angle: float) -> NDArray[np.float64]:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def shift(x: float = 0.0, z: float = 0.0) -> NDArray[np.float64]:
    out = np.eye(4)
    out[0, 3], out[2, 3] = x, z
    return out


def modified_dh_fk(q_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    pose = np.eye(4)
    for (alpha, a, d, offset), q in zip(DH_TABLE, q_rad, strict=True):
        pose = pose @ rot_x(alpha) @ shift(x=a) @ rot_z(q + offset) @ shift(z=d)
    return pose


def standard_dh_fk(q_rad: NDArray[np.float64]) -> NDArray[np.float64]:
    pose = np.eye(4)
    for (alpha, a, d, offset), q in zip(DH_TABLE, q_rad, strict=True):
        pose = pose @ rot_z(q + offset) @ shift(z=d) @ shift(x=a) @ rot_x(alpha)
    return pose


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel()


@pytest.mark.parametrize("q", POSES_RAD)
def test_fk_matches_the_modified_dh_oracle(model: RobotModel, q: tuple[float, ...]) -> None:
    q_rad = np.array(q)
    np.testing.assert_allclose(model.fk(q_rad), modified_dh_fk(q_rad), atol=1e-12)


def test_zero_pose_is_aubo_upright_pose(model: RobotModel) -> None:
    pose = model.fk(np.zeros(6))
    expected_m = [0.0, -(0.1215 + 0.094), 0.122 + 0.408 + 0.376 + 0.1025]
    np.testing.assert_allclose(pose[:3, 3], expected_m, atol=1e-12)
    np.testing.assert_allclose(pose[:3, 2], [0.0, -1.0, 0.0], atol=1e-12)  # flange faces sideways


def test_standard_dh_reading_of_the_same_table_does_not_give_that_pose() -> None:
    assert standard_dh_fk(np.zeros(6))[2, 3] < 0.0  # flange below the base: not AUBO's zero


def test_urdf_limits_match_joint_limits() -> None:
    urdf = pin.buildModelFromXML(aubo_i5_urdf())
    np.testing.assert_allclose(urdf.lowerPositionLimit, AUBO_I5_LIMITS.position_min_rad)
    np.testing.assert_allclose(urdf.upperPositionLimit, AUBO_I5_LIMITS.position_max_rad)
    np.testing.assert_allclose(urdf.velocityLimit, AUBO_I5_LIMITS.velocity_max_rad_s)


@pytest.mark.parametrize("q", POSES_RAD[1:])
def test_jacobian_matches_finite_differences_of_fk(model: RobotModel, q: tuple[float, ...]) -> None:
    q_rad = np.array(q)
    pose = model.fk(q_rad)
    numeric = np.empty((6, 6))
    h = 1e-7
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        moved = model.fk(q_rad + dq)
        numeric[:3, j] = (moved[:3, 3] - pose[:3, 3]) / h
        numeric[3:, j] = pin.log3(moved[:3, :3] @ pose[:3, :3].T) / h  # world-aligned omega
    np.testing.assert_allclose(model.jacobian(q_rad), numeric, atol=1e-5)


def test_tcp_offset_moves_the_tip_along_the_flange_z(model: RobotModel) -> None:
    tcp_in_flange = np.eye(4)
    tcp_in_flange[2, 3] = 0.15
    with_tool = RobotModel(tcp_in_flange=tcp_in_flange)
    q_rad = np.array(POSES_RAD[1])
    flange = model.fk(q_rad)
    np.testing.assert_allclose(with_tool.fk(q_rad), flange @ tcp_in_flange, atol=1e-12)


def test_wrong_joint_vector_shape_is_refused(model: RobotModel) -> None:
    with pytest.raises(RobotModelError, match=r"RobotModel.fk: q_rad must have shape \(6,\)"):
        model.fk(np.zeros(7))


def test_joint_names_follow_aubo_description(model: RobotModel) -> None:
    assert model.joint_names == (
        "shoulder_joint",
        "upperArm_joint",
        "foreArm_joint",
        "wrist1_joint",
        "wrist2_joint",
        "wrist3_joint",
    )
