"""The safety clamp: the last check on every joint target before it leaves the computer.

``SafetyClamp.clamp(q_target_rad, out)`` writes the joints to command this tick; whatever the
input (NaN, inf, 1e9, jumps, adversarial sequences) the commanded sequence q[n] (rad) obeys, per
joint j, with ``lo``/``hi`` the position limits moved inward by the margin and
``qd[n] = (q[n] - q[n-1]) / dt``:

- position: ``lo <= q[n] <= hi``;
- velocity: ``|qd[n]| <= v_max``; acceleration: ``|qd[n] - qd[n-1]| / dt <= a_max``;
- braking in time: ``qd[n]**2 / (2 a_max)`` is at most the distance to the limit it moves toward,
  so a stop at ``a_max`` always ends inside the limits;
- workspace: the model's TCP (the flange unless the model has a tool), ``fk(q[n])``, lies in the
  box ``workspace_min_m .. workspace_max_m`` (base frame, m).

Why all hold at once. Call the state after a tick (q, v) *safe* when

  (J) every joint satisfies the four joint conditions above, and
  (W) ``fk(q)`` lies in the box shrunk on every side by ``rho(v) = sum_j R_j v_j**2 / (2 a_j)``,
      where ``R_j`` bounds the distance from joint j's axis to the TCP in any configuration
      (the sum of the link lengths beyond joint j, :func:`axis_reach_m`).

The *brake step* lowers every joint speed by ``a_j dt`` (to zero at most). From a safe state it
gives a safe state: (J) because ``v**2/(2a) <= d`` implies ``(v - a dt)**2/(2a) + (v - a dt) dt
<= d - a dt**2/2``; (W) because the TCP moves at most ``sum_j R_j |v'_j| dt`` in the step (the
norm of Jacobian column j is the distance to axis j) while ``rho`` falls by at least as much
(``v**2/(2a) >= |v'| dt + v'**2/(2a)``). Each tick the clamp first builds a *candidate* whose
joint velocities lie, per joint, in the interval allowed by v_max, ``v +- a dt`` and the braking
speeds toward both limits; from a safe state that interval always holds the brake step's
velocity, so it is never empty and the candidate satisfies (J). The candidate is taken if its TCP
passes (W) (one forward kinematics), otherwise the brake step is taken (flag WORKSPACE). Both
keep the state safe, the start (the constructor's ``q0_rad`` at rest, refused unless inside the
limits and the box) is safe, so every tick is. ``hold()`` and a non-finite target take the brake
step: a category-2 stop reaching standstill within ``|v| / a`` plus one tick.

Inside the joint interval the candidate aims at the target: exactly onto it when the previous
tick reached its target, otherwise closing the gap at the speed that can still stop on a target
moving at its last velocity, so a jump in the target is followed without overshoot. The
guarantees hold to float64 rounding (positions are clipped exactly; velocities and accelerations
carry errors of order 1e-12 relative).

The arithmetic runs in the numba kernels of ``clamp_kernels.py`` on packed, preallocated arrays,
which the rig's compiled tick calls directly (:meth:`SafetyClamp.kernel_arrays`); through this
class a tick's only allocation is the 4x4 pose forward kinematics returns. A clamp uses its
model's work data: call it from the thread that owns the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from hilrig.errors import ParameterError
from hilrig.robot import AUBO_I5_LIMITS, FLANGE_FRAME, JOINTS, JointLimits, RobotModel
from hilrig.tick.clamp_kernels import (
    CAND_Q,
    HI,
    HOLDING,
    LO,
    NON_FINITE,
    TARGET,
    Clamp,
    Q,
    V,
    candidate,
    exceeds,
    finish,
)

__all__ = ["Clamp", "SafetyClamp", "SafetyConfig", "axis_reach_m"]

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class SafetyConfig:
    """Limits of the safety clamp.

    ``workspace_min_m``/``workspace_max_m``: a box in the base frame (m) the TCP must stay in. The
    default spans the AUBO-i5's reach in front of it (x from 0.15 m, clear of the base column, to
    0.85 m, just inside the 0.886 m reach; y +-0.6 m) above the table (z from 0.05 m) up to 0.9 m.
    ``position_margin_rad``: how far inside the joint limits the commands stay (default 0.05 rad,
    about 3 degrees). ``protective_force_n`` (norm of the Cartesian force, default 60 N) and
    ``protective_torque_nm`` (any joint, default 25 N*m) are the stop thresholds: an order of
    magnitude above the paper's collision forces and torques (at most 5 N and 5 N*m) and below
    the lowest quasi-static contact limit of ISO/TS 15066 (65 N, face). ``dt_s``: the tick (s).
    Raises :class:`~hilrig.errors.ParameterError` on an empty box, a margin that leaves no room,
    or a non-positive threshold or tick.
    """

    limits: JointLimits = AUBO_I5_LIMITS
    workspace_min_m: Vec3 = (0.15, -0.6, 0.05)
    workspace_max_m: Vec3 = (0.85, 0.6, 0.9)
    position_margin_rad: float = 0.05
    protective_force_n: float = 60.0
    protective_torque_nm: float = 25.0
    dt_s: float = 0.001

    def __post_init__(self) -> None:
        for name in ("protective_force_n", "protective_torque_nm", "dt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ParameterError(f"SafetyConfig.{name} must be finite and > 0, got {value}")
        if len(self.workspace_min_m) != 3 or len(self.workspace_max_m) != 3:
            raise ParameterError("SafetyConfig.workspace_min_m/max_m must have 3 values (x, y, z)")
        for axis, lo, hi in zip("xyz", self.workspace_min_m, self.workspace_max_m, strict=True):
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ParameterError(f"SafetyConfig: workspace {axis} range [{lo}, {hi}] is empty")
        margin = self.position_margin_rad
        low, high = self.lower_rad(), self.upper_rad()
        if not (math.isfinite(margin) and margin >= 0.0 and np.all(low < high)):
            raise ParameterError(
                f"SafetyConfig.position_margin_rad {margin} must be >= 0 and leave room in every "
                "joint's range"
            )

    def lower_rad(self) -> NDArray[np.float64]:
        """The lowest joint positions the clamp commands (6,), rad: limits plus margin."""
        return self.limits.lower_rad() + self.position_margin_rad

    def upper_rad(self) -> NDArray[np.float64]:
        """The highest joint positions the clamp commands (6,), rad: limits minus margin."""
        return self.limits.upper_rad() - self.position_margin_rad


def axis_reach_m(model: RobotModel) -> NDArray[np.float64]:
    """Per joint, a bound (m) on the distance from its axis to the model's TCP, any configuration.

    The triangle inequality along the serial chain: the lengths of every joint offset beyond
    joint j, the flange offset and the tool offset. Raises ParameterError for a URDF whose six
    joints are not one serial chain.
    """
    chain = pin.buildModelFromXML(model.urdf_xml)
    if list(chain.parents)[1:] != list(range(JOINTS)):
        raise ParameterError("axis_reach_m: the URDF's joints are not one serial chain")
    data = chain.createData()
    q_rad = np.zeros(JOINTS)
    flange_id = chain.getFrameId(FLANGE_FRAME)
    pin.framesForwardKinematics(chain, data, q_rad)
    tool_m = float(np.linalg.norm(model.fk(q_rad)[:3, 3] - data.oMf[flange_id].translation))
    offsets_m = [float(np.linalg.norm(chain.jointPlacements[k].translation)) for k in range(2, 7)]
    offsets_m.append(float(np.linalg.norm(chain.frames[flange_id].placement.translation)))
    return np.array([sum(offsets_m[j:]) + tool_m for j in range(JOINTS)])


class SafetyClamp:
    """Bounds joint targets (rad) before they are commanded; see the module docstring.

    ``q0_rad`` (6,) is where the robot stands (at rest) when the clamp starts. Raises
    :class:`~hilrig.errors.ParameterError` if it is not finite, outside the joint limits minus
    the margin, or puts the TCP outside the workspace box.
    """

    def __init__(
        self, config: SafetyConfig, model: RobotModel, q0_rad: NDArray[np.float64]
    ) -> None:
        self.config = config
        self._model = model
        q0 = np.array(q0_rad, dtype=np.float64)
        if q0.shape != (JOINTS,) or not np.all(np.isfinite(q0)):
            raise ParameterError(f"SafetyClamp: q0_rad must be 6 finite values, got {q0_rad}")
        limits = config.limits
        self._limits = np.array(
            [
                config.lower_rad(),
                config.upper_rad(),
                limits.velocity_max_rad_s,
                limits.acceleration_max_rad_s2,
                axis_reach_m(model),
            ]
        )
        outside = (q0 < self._limits[LO]) | (q0 > self._limits[HI])
        if np.any(outside):
            joint = int(np.argmax(outside)) + 1
            raise ParameterError(
                f"SafetyClamp: q0 joint {joint} = {q0[joint - 1]:.4f} rad is outside the limits "
                f"minus the {config.position_margin_rad} rad margin"
            )
        self._box = np.array([config.workspace_min_m, config.workspace_max_m], dtype=np.float64)
        tcp_m = model.fk(q0)[:3, 3]
        if not np.all((self._box[0] <= tcp_m) & (tcp_m <= self._box[1])):
            raise ParameterError(
                f"SafetyClamp: the TCP at q0, {np.round(tcp_m, 4).tolist()} m, is outside the "
                f"workspace box {config.workspace_min_m} .. {config.workspace_max_m} m"
            )
        self._dt = config.dt_s
        self._state = np.zeros((6, JOINTS))
        self._state[Q] = q0
        self._state[TARGET] = q0
        self._candidate_q = self._state[CAND_Q]  # a row view, passed to fk without slicing
        self._no_pose = np.eye(4)  # stands in for the TCP pose when braking needs none
        self._q_view = self._read_only(self._state[Q])
        self._qd_view = self._read_only(self._state[V])
        self._force_limit_n = config.protective_force_n
        self._torque_limit_nm = config.protective_torque_nm
        # numba loads compiled kernels on first call (~0.2 s): do it now, not on the first tick
        scratch = self._state.copy()
        candidate(q0, self._limits, scratch, self._dt)
        finish(self._no_pose, self._box, self._limits, scratch, self._dt, q0.copy(), True)
        exceeds(q0[:3].copy(), q0, 1.0, 1.0)

    def kernel_arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The packed (limits (5, 6), box (2, 3), state (6, 6)) the kernels work on: the clamp's
        own arrays, for a compiled caller that takes over its ticks (``hilrig.tick.kernel``)."""
        return self._limits, self._box, self._state

    @property
    def model(self) -> RobotModel:
        """The robot model whose TCP the workspace test places."""
        return self._model

    @property
    def q_rad(self) -> NDArray[np.float64]:
        """The last commanded joints (6,), rad: a read-only view that follows every tick."""
        return self._q_view

    @property
    def qd_rad_s(self) -> NDArray[np.float64]:
        """The last commanded joint velocities (6,), (q[n] - q[n-1]) / dt in rad/s; read-only."""
        return self._qd_view

    def clamp(self, q_target_rad: NDArray[np.float64], out: NDArray[np.float64]) -> int:
        """Write this tick's joint command (6,), rad, into ``out``; return the Clamp bitmask.

        ``q_target_rad`` (6,) is what the controller asks for; a NaN or inf anywhere in it makes
        the tick a hold. ``out`` (6,) float64 may be ``q_target_rad`` itself.
        """
        self._check(q_target_rad, "q_target_rad")
        self._check(out, "out")
        state = self._state
        flags: int = candidate(q_target_rad, self._limits, state, self._dt)
        if flags & NON_FINITE:
            finish(self._no_pose, self._box, self._limits, state, self._dt, out, True)
            return NON_FINITE | HOLDING
        pose = self._model.fk(self._candidate_q)
        braked: int = finish(pose, self._box, self._limits, state, self._dt, out, False)
        return braked or flags

    def hold(self, out: NDArray[np.float64]) -> int:
        """One tick of a controlled (category-2) stop: brake at the acceleration limit, then stay.

        Writes the command (6,), rad, into ``out`` and returns ``Clamp.HOLDING``. Call it every
        tick the loop must not track (stale data, lost link, faults); ``clamp`` resumes tracking
        from wherever the stop has got to.
        """
        self._check(out, "out")
        finish(self._no_pose, self._box, self._limits, self._state, self._dt, out, True)
        return HOLDING

    def stop_required(
        self, force_xyz_n: NDArray[np.float64], joint_torque_nm: NDArray[np.float64]
    ) -> bool:
        """True when the Cartesian force (3,), N, has a norm above the protective force or a
        joint torque (6,), N*m, exceeds the protective torque in magnitude, or any is not finite.
        """
        if force_xyz_n.shape != (3,) or joint_torque_nm.shape != (JOINTS,):
            raise ParameterError(
                f"SafetyClamp.stop_required: shapes (3,) and (6,) expected, got "
                f"{force_xyz_n.shape} and {joint_torque_nm.shape}"
            )
        exceeded: bool = exceeds(
            force_xyz_n, joint_torque_nm, self._force_limit_n, self._torque_limit_nm
        )
        return exceeded

    @staticmethod
    def _read_only(row: NDArray[np.float64]) -> NDArray[np.float64]:
        view = row.view()
        view.flags.writeable = False
        return view

    @staticmethod
    def _check(array: NDArray[np.float64], name: str) -> None:
        if array.shape != (JOINTS,) or array.dtype != np.float64:
            raise ParameterError(
                f"SafetyClamp: {name} must be a float64 array of shape (6,), "
                f"got {array.dtype} {array.shape}"
            )
