"""AUBO-i5 kinematics on pinocchio: forward kinematics, Jacobian, damped-least-squares IK.

The packaged URDF (``aubo_i5.urdf``) is written from AUBO's public DH values in the modified
(Craig) convention, ``T(i-1, i) = Rx(alpha[i-1]) Tx(a[i-1]) Rz(q[i] + offset[i]) Tz(d[i])``:

====  ============  ==========  ========  ==========
 i    alpha[i-1]    a[i-1] (m)  d[i] (m)  offset[i]
====  ============  ==========  ========  ==========
 1     0            0           0.122      pi
 2    -pi/2         0           0.1215    -pi/2
 3     pi           0.408       0          0
 4     pi           0.376       0         -pi/2
 5    -pi/2         0           0.1025     0
 6     pi/2         0           0.094      0
====  ============  ==========  ========  ==========

The modified convention is the one that reproduces AUBO's zero pose with these numbers: the arm
stands upright, the flange 1.0085 m above the base (d1 + a2 + a3 + d5) and 0.2155 m to its side
(d2 + d6), facing horizontally. Read as standard DH, the same table puts the flange below the base.

Frames: the base frame is ``base_link`` (z up through joint 1); poses are 4x4 homogeneous
matrices of the TCP in the base frame, in m. The TCP is the flange (DH frame 6) unless a
``tcp_in_flange`` transform is given. A :class:`RobotModel` holds pinocchio work data: use one
instance per thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from hilrig.errors import RobotModelError
from hilrig.robot.limits import AUBO_I5_LIMITS, JointLimits

JOINTS = 6
FLANGE_FRAME = "flange"
TCP_FRAME = "tcp"
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def aubo_i5_urdf() -> str:
    """The packaged AUBO-i5 URDF text (for the model, and as a recording attachment)."""
    return resources.files("hilrig.robot").joinpath("aubo_i5.urdf").read_text(encoding="utf-8")


@dataclass(frozen=True, slots=True)
class IkResult:
    """Outcome of :meth:`RobotModel.ik`.

    ``q_rad`` is the last iterate (inside the joint position limits even when not converged);
    ``iterations`` counts the Jacobian steps taken (0 when the start already met the
    tolerances); the errors are those of ``q_rad``: TCP position error (m) and rotation angle
    of the orientation error (rad).
    """

    q_rad: NDArray[np.float64]
    converged: bool
    iterations: int
    position_error_m: float
    rotation_error_rad: float


class RobotModel:
    """Kinematics of a 6-joint arm from a URDF (default: the packaged AUBO-i5).

    Raises :class:`~hilrig.errors.RobotModelError` if the URDF has no ``flange`` frame or not
    six joints, and from every method given a joint vector that is not of shape (6,).
    """

    def __init__(
        self,
        urdf_xml: str | None = None,
        *,
        tcp_in_flange: NDArray[np.float64] | None = None,
        limits: JointLimits = AUBO_I5_LIMITS,
    ) -> None:
        self.urdf_xml = aubo_i5_urdf() if urdf_xml is None else urdf_xml
        self.limits = limits
        self._model = pin.buildModelFromXML(self.urdf_xml)
        if self._model.nq != JOINTS:
            raise RobotModelError(f"URDF: expected {JOINTS} joints, got nq={self._model.nq}")
        if not self._model.existFrame(FLANGE_FRAME):
            raise RobotModelError(f"URDF: no frame named {FLANGE_FRAME!r}")
        flange_id = self._model.getFrameId(FLANGE_FRAME)
        if tcp_in_flange is None:
            self._tip_id = flange_id
        else:
            flange = self._model.frames[flange_id]
            placement = flange.placement * pin.SE3(np.asarray(tcp_in_flange, dtype=np.float64))
            self._tip_id = self._model.addFrame(
                pin.Frame(TCP_FRAME, flange.parentJoint, flange_id, placement, pin.OP_FRAME)
            )
        self._data = self._model.createData()
        self._lower_rad = limits.lower_rad()
        self._upper_rad = limits.upper_rad()
        self.joint_names: tuple[str, ...] = tuple(self._model.names[1:])

    def tcp_in_joint(self) -> tuple[int, NDArray[np.float64]]:
        """The joint the TCP frame is attached to (pinocchio index, 1..6) and the TCP's placement
        in that joint's frame (a new 4x4, m)."""
        frame = self._model.frames[self._tip_id]
        placement: NDArray[np.float64] = frame.placement.homogeneous.copy()
        return int(frame.parentJoint), placement

    def fk(self, q_rad: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pose of the TCP in the base frame at joints ``q_rad`` (6,), as a new 4x4 matrix (m)."""
        self._check(q_rad, "fk")
        pin.forwardKinematics(self._model, self._data, q_rad)
        pose: NDArray[np.float64] = pin.updateFramePlacement(
            self._model, self._data, self._tip_id
        ).homogeneous
        return pose

    def link_points(self, q_rad: NDArray[np.float64]) -> NDArray[np.float64]:
        """The arm as a polyline at ``q_rad`` (6,): the base, each joint's origin and the TCP,
        (8, 3), m, base frame (a new array)."""
        self._check(q_rad, "link_points")
        pin.forwardKinematics(self._model, self._data, q_rad)
        tip = pin.updateFramePlacement(self._model, self._data, self._tip_id).translation
        points = np.empty((JOINTS + 2, 3))
        points[0] = 0.0
        for j in range(1, JOINTS + 1):
            points[j] = self._data.oMi[j].translation
        points[JOINTS + 1] = tip
        return points

    def jacobian(self, q_rad: NDArray[np.float64]) -> NDArray[np.float64]:
        """TCP Jacobian (6, 6) at ``q_rad``, LOCAL_WORLD_ALIGNED.

        Rows 0-2 map joint rates (rad/s) to the linear velocity of the TCP origin (m/s), rows
        3-5 to the angular velocity (rad/s), both in base-frame axes.
        """
        self._check(q_rad, "jacobian")
        jac: NDArray[np.float64] = pin.computeFrameJacobian(
            self._model, self._data, q_rad, self._tip_id, _LWA
        )
        return jac

    def effective_mass_kg(
        self, q_rad: NDArray[np.float64], direction_in_base: NDArray[np.float64]
    ) -> float:
        """The arm's effective mass at the TCP along ``direction_in_base`` (3,) at ``q_rad``, kg:
        ``1 / (u^T J M^-1 J^T u)``, with the joint-space mass matrix M (pinocchio's CRBA, the
        URDF's inertials) and the TCP's linear Jacobian J, ``u`` the unit direction."""
        self._check(q_rad, "effective_mass_kg")
        u = np.asarray(direction_in_base, dtype=np.float64)
        u = u / np.linalg.norm(u)
        mass = pin.crba(self._model, self._data, q_rad)
        mass = np.triu(mass) + np.triu(mass, 1).T  # CRBA fills the upper triangle
        linear = self.jacobian(q_rad)[:3]
        mobility = linear @ np.linalg.solve(mass, linear.T)  # J M^-1 J^T, m/(N*s^2)
        return float(1.0 / (u @ mobility @ u))

    def ik(
        self,
        pose_in_base: NDArray[np.float64],
        q0_rad: NDArray[np.float64],
        *,
        max_iterations: int = 20,
        tol_position_m: float = 1e-6,
        tol_rotation_rad: float = 1e-6,
        damping: float = 1e-4,
        max_step_rad: float = 0.5,
    ) -> IkResult:
        """Joints that put the TCP at ``pose_in_base`` (4x4, m), starting from ``q0_rad`` (6,).

        Levenberg-Marquardt damped least squares: each step solves
        ``(J J^T + (|e|^2 + damping^2) I) y = e``, ``dq = J^T y`` with the position and
        rotation-vector error ``e`` in base axes, so it is Gauss-Newton near the solution and
        damped far from it or near singularities. Steps are scaled to at most ``max_step_rad``
        per joint and every iterate is clipped to the position limits. Warm-started from the
        previous tick's solution it converges in one or two steps.
        """
        self._check(q0_rad, "ik")
        model, data, tip = self._model, self._data, self._tip_id
        p_goal = pose_in_base[:3, 3]
        r_goal = pose_in_base[:3, :3]
        q = np.array(q0_rad, dtype=np.float64)
        error = np.empty(6)
        damping_sq = damping * damping
        tol_position_sq = tol_position_m * tol_position_m
        tol_rotation_sq = tol_rotation_rad * tol_rotation_rad
        iterations = 0
        while True:
            jac = pin.computeFrameJacobian(model, data, q, tip, _LWA)  # also updates oMf[tip]
            placement = data.oMf[tip]
            np.subtract(p_goal, placement.translation, out=error[:3])
            error[3:] = pin.log3(r_goal @ placement.rotation.T)
            position_sq = float(error[:3] @ error[:3])
            rotation_sq = float(error[3:] @ error[3:])
            converged = position_sq <= tol_position_sq and rotation_sq <= tol_rotation_sq
            if converged or iterations == max_iterations:
                return IkResult(
                    q, converged, iterations, math.sqrt(position_sq), math.sqrt(rotation_sq)
                )
            system = jac @ jac.T
            system.flat[::7] += position_sq + rotation_sq + damping_sq
            step = jac.T @ np.linalg.solve(system, error)
            largest = float(np.max(np.abs(step)))
            if largest > max_step_rad:
                step *= max_step_rad / largest
            q += step
            np.clip(q, self._lower_rad, self._upper_rad, out=q)
            iterations += 1

    def _check(self, q_rad: NDArray[np.float64], where: str) -> None:
        if q_rad.shape != (JOINTS,):
            raise RobotModelError(
                f"RobotModel.{where}: q_rad must have shape (6,), got {q_rad.shape}"
            )
