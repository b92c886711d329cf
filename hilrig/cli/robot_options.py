"""The robot link's options of ``hilrig record`` (and ``hilrig doctor``): which interface, which
controller, who logs in (the password from a file or the environment, never the command line),
and the servo stream's rate, look-ahead and gain."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.rig.kinds import RobotLinkKind

if TYPE_CHECKING:
    from hilrig.emulator.rig import RigEndpoints
    from hilrig.rig.arcs.settings import ArcsSettings
    from hilrig.rig.config_file import RigFile

RobotHost = Annotated[
    str | None,
    typer.Option(
        "--robot",
        metavar="HOST",
        help="The AUBO controller (ARCS) with --rig aubo: its JSON-RPC on 30004 and RTDE on "
        "30010 unless the config's \\[robot] table says other ports.",
    ),
]
RobotLinkOption = Annotated[
    RobotLinkKind,
    typer.Option(
        "--robot-link",
        help="arcs: AUBO's JSON-RPC + RTDE through AUBO's client (a real AUBO-i5); modbus: a "
        "joint-state stream and a Modbus target map (docs/protocols.md).",
    ),
]
PasswordFile = Annotated[
    Path | None,
    typer.Option(
        "--robot-password-file",
        help="A file whose first line is the controller's password (else the environment's "
        "HILRIG_AUBO_PASSWORD; the emulated rig's own is known).",
    ),
]
RobotUser = Annotated[str, typer.Option("--robot-user", help="The controller's user.")]
ServoRate = Annotated[
    float, typer.Option("--servo-rate", help="servoJoint calls per second, Hz (1..500).")
]
ServoLookahead = Annotated[
    float, typer.Option("--servo-lookahead", help="servoJoint's look-ahead, s (0.03..0.2).")
]
ServoGain = Annotated[float, typer.Option("--servo-gain", help="servoJoint's gain (100..2000).")]
RtdeRate = Annotated[
    float, typer.Option("--rtde-rate", help="The joint-state subscription's rate, Hz (1..500).")
]


def arcs_settings(
    *,
    emulated: bool,
    user: str,
    password_file: Path | None,
    servo_rate_hz: float,
    lookahead_s: float,
    gain: float,
    rtde_rate_hz: float,
) -> ArcsSettings:
    """The ARCS link's settings (host and ports come from the endpoints); raises
    ParameterError for a value outside AUBO's range or a password that cannot be read."""
    from hilrig.rig.arcs.settings import EMULATED_PASSWORD, ArcsSettings, password_from

    password = EMULATED_PASSWORD if emulated and password_file is None else None
    return ArcsSettings(
        user=user,
        password=password if password is not None else password_from(password_file),
        servo_rate_hz=servo_rate_hz,
        lookahead_s=lookahead_s,
        gain=gain,
        rtde_rate_hz=rtde_rate_hz,
    )


def real_endpoints(settings: RigFile, host: str | None) -> RigEndpoints:
    """A real rig's endpoints: the config's, with ``--robot HOST`` over its \\[robot] host;
    raises HilrigError saying what is missing."""
    from dataclasses import replace

    from hilrig.errors import HilrigError
    from hilrig.rig.arcs.settings import RPC_PORT, RTDE_PORT

    endpoints = settings.endpoints
    if endpoints is None:
        raise HilrigError(
            "--rig aubo needs --config with [endpoints] ft_wrist_port (and [robot] or --robot)"
        )
    if host is not None:  # the config's ports, else the controller's own
        endpoints = replace(
            endpoints,
            aubo_rpc=(host, endpoints.aubo_rpc[1] or RPC_PORT),
            aubo_rtde=(host, endpoints.aubo_rtde[1] or RTDE_PORT),
        )
    if not endpoints.aubo_rpc[0]:
        raise HilrigError("--rig aubo: no controller: give --robot HOST or [robot] host")
    return endpoints
