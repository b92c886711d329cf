"""The AUBO-i5 model: packaged URDF, kinematics on pinocchio (FK, Jacobian, IK) and limits.

model = RobotModel()                       # the packaged AUBO-i5, TCP at the flange
pose = model.fk(q_rad)                     # 4x4 TCP pose in the base frame, m
result = model.ik(pose, q_previous_rad)    # damped least squares, warm-started
chain = CompiledChain.from_model(model)    # the same as numba kernels: fk_into, ik_into, ...
"""

from hilrig.errors import RobotModelError
from hilrig.robot.kinematics import (
    IK_ERRORS,
    IK_WORK_ROWS,
    CompiledChain,
    fk_into,
    ik_into,
    ik_work,
    jacobian_into,
    log3_into,
    warm_up,
)
from hilrig.robot.limits import AUBO_I5_LIMITS, JointLimits
from hilrig.robot.model import FLANGE_FRAME, JOINTS, IkResult, RobotModel, aubo_i5_urdf

__all__ = [
    "AUBO_I5_LIMITS",
    "FLANGE_FRAME",
    "IK_ERRORS",
    "IK_WORK_ROWS",
    "JOINTS",
    "CompiledChain",
    "IkResult",
    "JointLimits",
    "RobotModel",
    "RobotModelError",
    "aubo_i5_urdf",
    "fk_into",
    "ik_into",
    "ik_work",
    "jacobian_into",
    "log3_into",
    "warm_up",
]
