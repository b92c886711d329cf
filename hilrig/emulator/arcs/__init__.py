"""An emulated AUBO ARCS controller that AUBO's own client (pyaubo-sdk 0.24.1) accepts.

``wire`` (the JSON-RPC and RTDE framings, login text and RTDE hello; pure), ``controller`` (robot,
safety and servo modes, users, faults, this slot's joint values), ``rpc_server`` and
``rtde_server`` (devices of the emulated rig's slot loop). docs/protocols.md, "ARCS", says what
is AUBO's documentation and what was observed against the client.
"""

from hilrig.emulator.arcs.controller import (
    ArcsConfig,
    ArcsController,
    RobotMode,
    SafetyMode,
    ServoCode,
)
from hilrig.emulator.arcs.rpc_server import EmulatedArcsRpcServer
from hilrig.emulator.arcs.rtde_server import OUTPUTS, EmulatedArcsRtdeServer

__all__ = [
    "OUTPUTS",
    "ArcsConfig",
    "ArcsController",
    "EmulatedArcsRpcServer",
    "EmulatedArcsRtdeServer",
    "RobotMode",
    "SafetyMode",
    "ServoCode",
]
