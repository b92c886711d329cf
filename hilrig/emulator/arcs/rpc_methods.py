"""The JSON-RPC methods the emulated controller answers, and how it answers the rest.

Method names and parameter names as pyaubo-sdk 0.24.1 sends them (params by name; AUBO's
headers show positional arrays in their examples, so a list is taken in the documented order
too). Anything else: JSON-RPC 2.0's error ``-32601 Method not found``; parameters that are not
what a method takes: ``-32602 Invalid params``. Each method's result has the JSON type the client
parses (``isServoModeEnabled`` a boolean: the client raises on a number).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from hilrig.emulator.arcs.controller import (
    INTERFACE_VERSION,
    ROBOT_NAME,
    ArcsController,
    RobotMode,
    SafetyMode,
)

METHOD_NOT_FOUND = -32601
INVALID_PARAMS = -32602
PARSE_ERROR = -32700
INVALID_REQUEST = -32600
NOT_LOGGED_IN = -32000  # our choice (a server error code of JSON-RPC 2.0's range)
NOT_LOGGED_IN_MESSAGE = "Not logged in"
LOGIN_FAILED_MESSAGE = "Login failed: wrong user or password"
# answered before login: the client's connect() asks the interface version first
BEFORE_LOGIN = frozenset({"SystemInfo.getInterfaceVersionCode"})


@dataclass(frozen=True)
class RpcError(Exception):
    """A JSON-RPC 2.0 error object's code and message."""

    code: int
    message: str

    def as_json(self) -> dict[str, object]:
        return {"code": self.code, "message": self.message}


Handler = Callable[[ArcsController, dict[str, Any]], object]


def _joints(values: Callable[[ArcsController], Any]) -> Handler:
    return lambda arcs, _: values(arcs).tolist()


_R = ROBOT_NAME
# method: (parameter names in the documented order, handler)
METHODS: Mapping[str, tuple[tuple[str, ...], Handler]] = {
    "SystemInfo.getInterfaceVersionCode": ((), lambda arcs, _: INTERFACE_VERSION),
    "getRobotNames": ((), lambda arcs, _: [ROBOT_NAME]),
    "getAxisNames": ((), lambda arcs, _: []),
    f"{_R}.MotionControl.setServoMode": (
        ("enable",),
        lambda arcs, p: arcs.set_servo_mode(_flag(p["enable"]), time.monotonic_ns()),
    ),
    f"{_R}.MotionControl.isServoModeEnabled": ((), lambda arcs, _: arcs.servo_mode),
    f"{_R}.MotionControl.servoJoint": (
        ("q", "a", "v", "t", "lookahead_time", "gain"),
        lambda arcs, p: arcs.servo_joint(p["q"], time.monotonic_ns()),
    ),
    f"{_R}.MotionControl.stopJoint": (
        ("acc",),
        lambda arcs, _: arcs.stop_joint(time.monotonic_ns()),
    ),
    f"{_R}.RobotState.getJointPositions": ((), _joints(lambda arcs: arcs.q_rad)),
    f"{_R}.RobotState.getJointSpeeds": ((), _joints(lambda arcs: arcs.qd_rad_s)),
    f"{_R}.RobotState.getJointTorqueSensors": ((), _joints(lambda arcs: arcs.torque_nm)),
    f"{_R}.RobotState.getJointCurrents": ((), _joints(lambda arcs: arcs.current_a)),
    f"{_R}.RobotState.getJointTargetPositions": ((), _joints(lambda arcs: arcs.target_q_rad)),
    f"{_R}.RobotState.getRobotModeType": ((), lambda arcs, _: arcs.robot_mode.name),
    f"{_R}.RobotState.getSafetyModeType": ((), lambda arcs, _: arcs.safety_mode.name),
    f"{_R}.RobotState.isPowerOn": ((), lambda arcs, _: arcs.robot_mode >= RobotMode.PowerOn),
    f"{_R}.RobotState.isCollisionOccurred": (
        (),
        lambda arcs, _: arcs.safety_mode is SafetyMode.ProtectiveStop,
    ),
}


def _flag(value: object) -> bool:
    if not isinstance(value, bool):
        raise RpcError(INVALID_PARAMS, "Invalid params")
    return value


def call(arcs: ArcsController, method: str, params: object) -> object:
    """The result of ``method`` with ``params`` (an object, an array or absent); raises
    RpcError."""
    entry = METHODS.get(method)
    if entry is None:
        raise RpcError(METHOD_NOT_FOUND, "Method not found")
    names, handler = entry
    if params is None:
        params = {}
    if isinstance(params, list):
        if len(params) > len(names):
            raise RpcError(INVALID_PARAMS, "Invalid params")
        params = dict(zip(names, params, strict=False))
    if not isinstance(params, dict) or not all(name in params for name in names):
        raise RpcError(INVALID_PARAMS, "Invalid params")
    return handler(arcs, params)
