"""Rows of STATE_DTYPE (the compiled decoder's, the client's) as the reference decoder's frames."""

from typing import Any

from hilrig.drivers.robot_state.wire import RobotState, RobotStatus


def as_state(row: Any) -> RobotState:
    """The RobotState of one STATE_DTYPE row (its receive time left out)."""
    return RobotState(
        int(row["seq"]),
        int(row["device_t_ns"]),
        tuple(row["q"].tolist()),
        tuple(row["qd"].tolist()),
        tuple(row["tau"].tolist()),
        RobotStatus(int(row["status"])),
    )
