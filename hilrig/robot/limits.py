"""Joint limits of the AUBO-i5: position, velocity, acceleration and jerk, per joint J1..J6.

Position and velocity limits are AUBO's published numbers (docs/rig.md). AUBO publishes
no joint acceleration limits; the values here are hilrig's conservative choice: about one second
from rest to full speed on every joint, far below what the drives can do, because the safety
clamp uses them to bound every commanded step whatever the controller asks. Nor does AUBO
publish jerk limits; the clamp bounds none (its controlled stop brakes at full acceleration at
once), but hilrig's task trajectories keep below these (full acceleration built up in 0.1 s at
the least), so the motion they ask for is smooth (:mod:`hilrig.tick.task_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hilrig.errors import ParameterError

Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class JointLimits:
    """Symmetric or asymmetric limits of six joints, in rad, rad/s, rad/s^2 and rad/s^3.

    Raises :class:`~hilrig.errors.ParameterError` if a lower bound is not below its upper bound
    or a velocity, acceleration or jerk limit is not positive.
    """

    position_min_rad: Six
    position_max_rad: Six
    velocity_max_rad_s: Six
    acceleration_max_rad_s2: Six
    # not published by AUBO either: kept by the tasks, not the clamp (see module docstring)
    jerk_max_rad_s3: Six = (30.0, 30.0, 30.0, 30.0, 30.0, 30.0)

    def __post_init__(self) -> None:
        for j, (lo, hi) in enumerate(
            zip(self.position_min_rad, self.position_max_rad, strict=True)
        ):
            if not lo < hi:
                raise ParameterError(f"joint {j + 1}: position_min_rad {lo} >= max {hi}")
        for name in ("velocity_max_rad_s", "acceleration_max_rad_s2", "jerk_max_rad_s3"):
            values: Six = getattr(self, name)
            if not all(v > 0 for v in values):
                raise ParameterError(f"JointLimits.{name}: every value must be > 0, got {values}")

    def lower_rad(self) -> NDArray[np.float64]:
        """Position lower bounds as a new (6,) array, rad."""
        return np.array(self.position_min_rad, dtype=np.float64)

    def upper_rad(self) -> NDArray[np.float64]:
        """Position upper bounds as a new (6,) array, rad."""
        return np.array(self.position_max_rad, dtype=np.float64)

    def contains(self, q_rad: NDArray[np.float64]) -> bool:
        """True when every joint of ``q_rad`` (6,) lies inside its position limits (inclusive)."""
        return bool(
            np.all(q_rad >= self.position_min_rad) and np.all(q_rad <= self.position_max_rad)
        )


AUBO_I5_LIMITS = JointLimits(
    position_min_rad=(-3.05, -3.05, -3.05, -3.05, -3.05, -3.05),
    position_max_rad=(3.05, 3.05, 3.05, 3.05, 3.05, 3.05),
    velocity_max_rad_s=(3.14, 3.14, 3.14, 2.6, 2.6, 2.6),
    # Not published by AUBO: conservative, ~1 s from rest to full speed (see module docstring).
    acceleration_max_rad_s2=(3.0, 3.0, 3.0, 3.0, 3.0, 3.0),
)
