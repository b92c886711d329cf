"""Compiled kinematics: :class:`RobotModel`'s FK, Jacobian and IK as allocation-free numba kernels.

The kernels reproduce ``RobotModel.fk``, ``.jacobian`` and ``.ik`` (pinocchio) to float64
rounding and can be called from other ``@njit`` code. They read the chain from two or three
packed float64 arrays built once by :meth:`CompiledChain.from_model`:

- ``frames`` (7, 4, 4): ``frames[i]`` is joint i's placement in its parent's frame (joint i-1,
  the base for i = 0) at q = 0; ``frames[TIP]`` is the TCP in the last joint's frame (m);
- ``axes`` (6, 3): each revolute joint's unit axis in its own frame;
- ``limits`` (2, 6): rows ``LOWER`` and ``UPPER``, the joint position limits IK clips to (rad).

Poses are 4x4 homogeneous matrices of the TCP in the base frame (m). ``ik_into`` works in a
caller-owned ``work`` array (:func:`ik_work`, rows named ``IK_*``) and leaves the errors of its
last iterate in ``work[IK_ERRORS, 0]`` (position, m) and ``work[IK_ERRORS, 1]`` (rotation, rad).
Kernels use numpy's error model: a zero pivot gives inf/NaN instead of raising.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from hilrig.compiled import njit
from hilrig.errors import RobotModelError
from hilrig.robot.model import JOINTS, IkResult, RobotModel

F64 = NDArray[np.float64]
TIP = JOINTS  # frames[TIP]: the TCP in the last joint's frame
LOWER, UPPER = 0, 1  # rows of limits
# Rows of the IK work array (IK_WORK_ROWS, 6): the TCP Jacobian, the 6x6 system (then its
# Cholesky factor), the error e, y = system^-1 e, the joint step, the TCP pose (rows
# IK_POSE..IK_POSE+3, columns 0-3) and the last iterate's errors (position m, rotation rad).
IK_JACOBIAN, IK_SYSTEM, IK_ERROR, IK_Y, IK_STEP, IK_POSE, IK_ERRORS = 0, 6, 12, 13, 14, 15, 19
IK_WORK_ROWS = 20
_EPS = float(np.finfo(np.float64).eps)
_PREC = _EPS ** (1.0 / 3.0)  # pinocchio's TaylorSeriesExpansion<double>::precision<2>()
_AXES = {f"JointModelR{name}": np.eye(3)[k] for k, name in enumerate("XYZ")}
_UNALIGNED = "JointModelRevoluteUnaligned"


@dataclass(frozen=True)
class CompiledChain:
    """A serial chain of six revolute joints as packed arrays for the kernels (layout above)."""

    frames: F64
    axes: F64
    limits: F64

    @classmethod
    def from_model(cls, model: RobotModel) -> CompiledChain:
        """Extract ``model``'s chain, TCP and position limits.

        Raises RobotModelError unless the URDF's joints form one serial chain of six revolute
        joints (RX/RY/RZ or unaligned, unit axis) with the TCP on the last.
        """
        chain = pin.buildModelFromXML(model.urdf_xml)
        if chain.nv != JOINTS or list(chain.parents)[1:] != list(range(JOINTS)):
            raise RobotModelError("CompiledChain: the URDF's joints are not one serial chain")
        frames = np.zeros((JOINTS + 1, 4, 4))
        axes = np.zeros((JOINTS, 3))
        for i in range(1, JOINTS + 1):
            joint, kind = chain.joints[i], chain.joints[i].shortname()
            if (kind not in _AXES and kind != _UNALIGNED) or joint.nq != 1:
                name = chain.names[i]
                raise RobotModelError(f"CompiledChain: joint {name!r} is {kind}, not revolute")
            axes[i - 1] = joint.extract().axis if kind == _UNALIGNED else _AXES[kind]
            if abs(float(np.linalg.norm(axes[i - 1])) - 1.0) > 1e-12:
                raise RobotModelError(f"CompiledChain: joint {chain.names[i]!r}: axis not unit")
            frames[i - 1] = chain.jointPlacements[i].homogeneous
        parent, tcp = model.tcp_in_joint()
        if parent != JOINTS:
            raise RobotModelError(f"CompiledChain: the TCP is on joint {parent}, not joint 6")
        frames[TIP] = tcp
        limits = np.array([model.limits.lower_rad(), model.limits.upper_rad()])
        for array in (frames, axes, limits):
            array.flags.writeable = False
        return cls(frames, axes, limits)

    def fk(self, q_rad: F64) -> F64:
        """TCP pose in the base frame at ``q_rad`` (6,), a new 4x4 (m)."""
        pose = np.empty((4, 4))
        fk_into(self.frames, self.axes, _joints(q_rad, "fk"), pose)
        return pose

    def jacobian(self, q_rad: F64) -> F64:
        """TCP Jacobian (6, 6) at ``q_rad``, LOCAL_WORLD_ALIGNED, as RobotModel.jacobian."""
        pose, jac = np.empty((4, 4)), np.empty((6, 6))
        jacobian_into(self.frames, self.axes, _joints(q_rad, "jacobian"), pose, jac)
        return jac

    def ik(
        self,
        pose_in_base: F64,
        q0_rad: F64,
        *,
        max_iterations: int = 20,
        tol_position_m: float = 1e-6,
        tol_rotation_rad: float = 1e-6,
        damping: float = 1e-4,
        max_step_rad: float = 0.5,
    ) -> IkResult:
        """RobotModel.ik on the compiled kernel (same options, same result)."""
        q = _joints(q0_rad, "ik").copy()
        goal = np.ascontiguousarray(pose_in_base, dtype=np.float64)
        work = ik_work()
        code = ik_into(
            self.frames, self.axes, self.limits, goal, q, max_iterations,
            tol_position_m, tol_rotation_rad, damping, max_step_rad, work,
        )  # fmt: skip
        converged = code >= 0
        iterations = code if converged else -code - 1
        errors = work[IK_ERRORS]
        return IkResult(q, converged, iterations, float(errors[0]), float(errors[1]))


def ik_work() -> F64:
    """A new work array for :func:`ik_into`, (IK_WORK_ROWS, 6)."""
    return np.zeros((IK_WORK_ROWS, JOINTS))


def warm_up(chain: CompiledChain) -> None:
    """Call every kernel once on C-contiguous float64 arrays, so no later call compiles or
    loads from the cache (do it before the real-time loop starts)."""
    q = np.zeros(JOINTS)
    chain.jacobian(q)
    chain.ik(chain.fk(q), q, max_iterations=1)
    log3_into(np.eye(3), np.empty(3))


def _joints(q_rad: F64, where: str) -> F64:
    if q_rad.shape != (JOINTS,):
        raise RobotModelError(
            f"CompiledChain.{where}: q_rad must have shape (6,), got {q_rad.shape}"
        )
    return np.ascontiguousarray(q_rad, dtype=np.float64)


@njit(cache=True, error_model="numpy")
def _identity(pose: F64) -> None:
    for r in range(4):
        for c in range(4):
            pose[r, c] = 1.0 if r == c else 0.0


@njit(cache=True, error_model="numpy")
def _times_placement(pose: F64, placement: F64) -> None:
    """pose <- pose @ placement, both rigid 4x4 (last row 0 0 0 1)."""
    for r in range(3):
        a0, a1, a2, a3 = pose[r, 0], pose[r, 1], pose[r, 2], pose[r, 3]
        for c in range(4):
            pose[r, c] = a0 * placement[0, c] + a1 * placement[1, c] + a2 * placement[2, c]
        pose[r, 3] += a3


@njit(cache=True, error_model="numpy")
def _times_rotation(pose: F64, axis: F64, angle_rad: float) -> None:
    """pose[:3, :3] <- pose[:3, :3] @ R(axis, angle): pinocchio's toRotationMatrix."""
    x, y, z = axis[0], axis[1], axis[2]
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    vx, vy, vz = (1.0 - c) * x, (1.0 - c) * y, (1.0 - c) * z
    r00, r11, r22 = vx * x + c, vy * y + c, vz * z + c
    r01, r10 = vx * y - s * z, vx * y + s * z
    r02, r20 = vx * z + s * y, vx * z - s * y
    r12, r21 = vy * z - s * x, vy * z + s * x
    for r in range(3):
        a0, a1, a2 = pose[r, 0], pose[r, 1], pose[r, 2]
        pose[r, 0] = a0 * r00 + a1 * r10 + a2 * r20
        pose[r, 1] = a0 * r01 + a1 * r11 + a2 * r21
        pose[r, 2] = a0 * r02 + a1 * r12 + a2 * r22


@njit(cache=True, error_model="numpy")
def fk_into(frames: F64, axes: F64, q_rad: F64, pose_out: F64) -> None:
    """Write the TCP pose in the base frame at ``q_rad`` (6,) into ``pose_out`` (4x4, m)."""
    _identity(pose_out)
    for i in range(axes.shape[0]):
        _times_placement(pose_out, frames[i])
        _times_rotation(pose_out, axes[i], q_rad[i])
    _times_placement(pose_out, frames[axes.shape[0]])


@njit(cache=True, error_model="numpy")
def jacobian_into(frames: F64, axes: F64, q_rad: F64, pose_out: F64, jac_out: F64) -> None:
    """Write the TCP Jacobian at ``q_rad`` into ``jac_out`` (6, 6), LOCAL_WORLD_ALIGNED (rows
    0-2: TCP origin velocity m/s, 3-5: angular velocity rad/s, base axes), the pose into
    ``pose_out``."""
    _identity(pose_out)
    joints = axes.shape[0]
    for i in range(joints):
        _times_placement(pose_out, frames[i])
        _times_rotation(pose_out, axes[i], q_rad[i])
        for r in range(3):  # joint origin (rows 0-2, for now) and axis in the base frame
            jac_out[r, i] = pose_out[r, 3]
            w = pose_out[r, 0] * axes[i, 0] + pose_out[r, 1] * axes[i, 1]
            jac_out[3 + r, i] = w + pose_out[r, 2] * axes[i, 2]
    _times_placement(pose_out, frames[joints])
    for i in range(joints):  # v = w x (p_tcp - p_joint)
        dx = pose_out[0, 3] - jac_out[0, i]
        dy = pose_out[1, 3] - jac_out[1, i]
        dz = pose_out[2, 3] - jac_out[2, i]
        wx, wy, wz = jac_out[3, i], jac_out[4, i], jac_out[5, i]
        jac_out[0, i] = wy * dz - wz * dy
        jac_out[1, i] = wz * dx - wx * dz
        jac_out[2, i] = wx * dy - wy * dx


@njit(cache=True, error_model="numpy")
def log3_into(rotation: F64, out: F64) -> float:
    """Rotation vector of ``rotation`` (3x3) into ``out`` (3,); returns the angle (rad).

    pinocchio's log3 step for step: renormalise, the antisymmetric part scaled by
    theta/sin(theta) (a series near 0), the diagonal formula near pi.
    """
    n0 = math.sqrt(rotation[0, 0] ** 2 + rotation[1, 0] ** 2 + rotation[2, 0] ** 2)
    n1 = math.sqrt(rotation[0, 1] ** 2 + rotation[1, 1] ** 2 + rotation[2, 1] ** 2)
    b0, b1, b2 = rotation[0, 1] / n1, rotation[1, 1] / n1, rotation[2, 1] / n1
    a0, a1, a2 = rotation[0, 0] / n0, rotation[1, 0] / n0, rotation[2, 0] / n0
    c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    a0, a1, a2 = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
    # columns a, b, c: R(i, 0) = a_i, R(i, 1) = b_i, R(i, 2) = c_i
    trace = a0 + (b1 + c2)  # the summation order of Eigen's trace()
    cos_value = (trace - 1.0) / 2.0
    if cos_value >= -1.0 + _PREC:
        if trace <= 3.0 - _PREC:
            theta = math.acos(cos_value)
        else:
            theta = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
        u0, u1, u2 = 0.5 * (b2 - c1), 0.5 * (c0 - a2), 0.5 * (a1 - b0)
        if theta >= _PREC:
            t = theta / math.sin(theta)
        else:
            norm_sq = u0 * u0 + u1 * u1 + u2 * u2
            t = 1.0 + norm_sq / 6.0 + norm_sq * norm_sq * 3.0 / 40.0
        out[0], out[1], out[2] = t * u0, t * u1, t * u2
        return theta
    # near pi: the axis from the column of the largest diagonal entry (pinocchio's choice)
    v0, v1, v2 = 2.0 * a0 - trace + 1.0, 2.0 * b1 - trace + 1.0, 2.0 * c2 - trace + 1.0
    k = (0 if v0 >= v2 else 2) if v0 >= v1 else (1 if v1 >= v2 else 2)
    val = v0 if k == 0 else (v1 if k == 1 else v2)
    if k == 0:  # R(i1, i0) + R(i0, i1), R(i2, i0) + R(i0, i2), R(i2, i1), R(i1, i2)
        p1, p2, up, down = a1 + b0, a2 + c0, b2, c1
    elif k == 1:
        p1, p2, up, down = b2 + c1, b0 + a1, c0, a2
    else:
        p1, p2, up, down = c0 + a2, c1 + b2, a1, b0
    s = math.sqrt(val + _EPS + _EPS * _EPS) * (1.0 if up >= down else -1.0)
    x0, x1, x2 = s / 2.0, 1.0 / (2.0 * s) * p1, 1.0 / (2.0 * s) * p2
    w = 1.0 / (2.0 * s) * (up - down)
    norm = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    theta = 2.0 * math.atan2(norm, w)
    out[k] = x0 / norm * theta
    out[(k + 1) % 3] = x1 / norm * theta
    out[(k + 2) % 3] = x2 / norm * theta
    return theta


@njit(cache=True, error_model="numpy")
def _solve_spd(system: F64, rhs: F64, x_out: F64) -> None:
    """Solve ``system @ x = rhs`` (SPD, n x n) by Cholesky; overwrites system's lower triangle."""
    n = rhs.shape[0]
    for j in range(n):
        d = system[j, j]
        for k in range(j):
            d -= system[j, k] * system[j, k]
        d = math.sqrt(d)
        system[j, j] = d
        for i in range(j + 1, n):
            s = system[i, j]
            for k in range(j):
                s -= system[i, k] * system[j, k]
            system[i, j] = s / d
    for i in range(n):
        s = rhs[i]
        for k in range(i):
            s -= system[i, k] * x_out[k]
        x_out[i] = s / system[i, i]
    for i in range(n - 1, -1, -1):
        s = x_out[i]
        for k in range(i + 1, n):
            s -= system[k, i] * x_out[k]
        x_out[i] = s / system[i, i]


@njit(cache=True, error_model="numpy")
def ik_into(
    frames: F64,
    axes: F64,
    limits: F64,
    goal_pose: F64,
    q_inout: F64,
    max_iterations: int,
    tol_position_m: float,
    tol_rotation_rad: float,
    damping: float,
    max_step_rad: float,
    work: F64,
) -> int:
    """RobotModel.ik in place: move ``q_inout`` (6,) toward joints that put the TCP at
    ``goal_pose`` (4x4, base frame, m).

    Returns the Jacobian steps taken when converged, ``-(steps + 1)`` when not (after
    ``max_iterations`` steps; at most 0 means: evaluate the start only). The last iterate's
    errors are left in ``work[IK_ERRORS, :2]`` (m, rad); ``work`` is (IK_WORK_ROWS, 6).
    """
    joints = q_inout.shape[0]
    jac = work[IK_JACOBIAN : IK_JACOBIAN + 6]
    system = work[IK_SYSTEM : IK_SYSTEM + 6]
    error, y, step = work[IK_ERROR], work[IK_Y], work[IK_STEP]
    pose = work[IK_POSE : IK_POSE + 4, :4]
    damping_sq = damping * damping
    tol_position_sq = tol_position_m * tol_position_m
    tol_rotation_sq = tol_rotation_rad * tol_rotation_rad
    iterations = 0
    while True:
        jacobian_into(frames, axes, q_inout, pose, jac)
        for r in range(3):
            error[r] = goal_pose[r, 3] - pose[r, 3]
            for c in range(3):  # system[:3, :3] <- R_goal @ R^T, the rotation error
                system[r, c] = (
                    goal_pose[r, 0] * pose[c, 0]
                    + goal_pose[r, 1] * pose[c, 1]
                    + goal_pose[r, 2] * pose[c, 2]
                )
        log3_into(system[:3, :3], error[3:])
        position_sq = error[0] * error[0] + error[1] * error[1] + error[2] * error[2]
        rotation_sq = error[3] * error[3] + error[4] * error[4] + error[5] * error[5]
        converged = position_sq <= tol_position_sq and rotation_sq <= tol_rotation_sq
        if converged or iterations >= max_iterations:
            work[IK_ERRORS, 0] = math.sqrt(position_sq)
            work[IK_ERRORS, 1] = math.sqrt(rotation_sq)
            return iterations if converged else -(iterations + 1)
        shift = position_sq + rotation_sq + damping_sq
        for r in range(6):
            for c in range(6):
                s = 0.0
                for k in range(joints):
                    s += jac[r, k] * jac[c, k]
                system[r, c] = s + shift if r == c else s
        _solve_spd(system, error, y)
        largest = 0.0
        for j in range(joints):
            s = 0.0
            for r in range(6):
                s += jac[r, j] * y[r]
            step[j] = s
            if abs(s) > largest or s != s:  # a NaN stays, as in np.max
                largest = abs(s)
        if largest > max_step_rad:
            scale = max_step_rad / largest
            for j in range(joints):
                step[j] *= scale
        for j in range(joints):
            q = q_inout[j] + step[j]
            if q < limits[LOWER, j]:
                q = limits[LOWER, j]
            elif q > limits[UPPER, j]:
                q = limits[UPPER, j]
            q_inout[j] = q
        iterations += 1
