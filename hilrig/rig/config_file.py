"""A session's config file (TOML) and where a new session's recording goes.

    [endpoints]                       # a real rig
    ft_wrist_port = "/dev/ttyUSB0"
    robot_state = "host:8002"         # with --robot-link modbus only
    modbus = "host:502"               # Modbus RTU over TCP, likewise
    [robot]                           # the AUBO controller (ARCS); --robot HOST overrides host
    host = "192.168.1.10"
    rpc_port = 30004                  # the controller's defaults
    rtde_port = 30010
    [trajectory]                      # the task: a trajectory's name and its builder's options
    name = "waypoints"
    points = [[1.0, 0.0, 0.02, 0.0]]  # [t_s, dx_m, dy_m, dz_m], ...
    [scenario]                        # the emulated volunteer and its settings
    name = "hand-contact"
    stiffness_n_m = 800
    direction_in_base = [1, 0, 0]

Any table may be left out: the emulated rig needs no endpoints. No password here: it comes from
a file (``--robot-password-file``) or the environment.
"""

from __future__ import annotations

import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import HilrigError, OutputError
from hilrig.outputs import check_new_file, nearest_existing
from hilrig.recording.session_ids import new_session_id
from hilrig.rig.arcs.settings import RPC_PORT, RTDE_PORT

#: Where new recordings go unless told.
RECORDINGS = Path("recordings")


@dataclass(frozen=True)
class RigFile:
    """What a config file sets: the real rig's endpoints, the trajectory and its options."""

    endpoints: RigEndpoints | None = None
    trajectory: str | None = None
    trajectory_options: dict[str, object] = field(default_factory=dict)
    scenario: str | None = None
    scenario_settings: dict[str, object] = field(default_factory=dict)


def read_rig_file(path: Path) -> RigFile:
    """The config file at ``path``; raises HilrigError naming the file and what is wrong."""
    try:
        config = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise HilrigError(f"{path}: cannot read the config ({err})") from err
    options = _table(path, config, "trajectory")
    name = options.pop("name", None)
    if name is not None:
        _check_trajectory(path, str(name), options)
    settings = _table(path, config, "scenario")
    scenario = settings.pop("name", None)
    return RigFile(
        endpoints=(
            _endpoints(path, config["endpoints"], _table(path, config, "robot"))
            if "endpoints" in config
            else None
        ),
        trajectory=None if name is None else str(name),
        trajectory_options=options,
        scenario=None if scenario is None else str(scenario),
        scenario_settings=settings,
    )


def _table(path: Path, config: dict[str, Any], name: str) -> dict[str, object]:
    table = config.get(name, {})
    if not isinstance(table, dict):
        raise HilrigError(f"{path}: {name} must be a table ([{name}] with name = ...)")
    return dict(table)


def _check_trajectory(path: Path, name: str, options: dict[str, object]) -> None:
    """Build the trajectory once from a neutral pose: a bad waypoint is named with the file."""
    import numpy as np

    from hilrig.tick.trajectory import make_trajectory

    try:
        make_trajectory(name, np.eye(4), **options)
    except HilrigError as err:
        raise HilrigError(f"{path}: [trajectory] {err}") from None


def _endpoints(path: Path, table: Any, robot: dict[str, object]) -> RigEndpoints:
    try:
        ft_wrist_port = str(table["ft_wrist_port"])
        robot_state, modbus = _host_port(table.get("robot_state")), _host_port(table.get("modbus"))
    except (KeyError, ValueError, TypeError, AttributeError) as err:
        raise HilrigError(f"{path}: no valid [endpoints] table ({err})") from err
    if "password" in robot:
        raise HilrigError(f"{path}: [robot] password: a password has no place in a config file")
    try:
        host = str(robot.get("host", ""))
        rpc_port, rtde_port = (int(str(robot.get(k, d))) for k, d in _PORTS)
    except ValueError as err:
        raise HilrigError(f"{path}: no valid [robot] table ({err})") from err
    no_host = not host  # no controller named: its ports wait for --robot HOST
    return RigEndpoints(
        ft_wrist_port,
        robot_state,
        modbus,
        ("", 0) if no_host else (host, rpc_port),
        ("", 0) if no_host else (host, rtde_port),
    )


_PORTS = (("rpc_port", RPC_PORT), ("rtde_port", RTDE_PORT))


def _host_port(value: object) -> tuple[str, int]:
    """``"host:port"`` as a pair; ("", 0) for none."""
    if value is None:
        return ("", 0)
    host, port = str(value).rsplit(":", 1)
    return (host, int(port))


def session_path(out: Path | None, stem: str) -> Path:
    """``out``, or ``recordings/<stem>-<local date-time>-<5 random characters>.mcap`` (two
    sessions started in one second get two names): a new file (checked, not made: the session
    makes it and its folder when it starts). Raises OutputError (one line) if a file is there
    already or its folder cannot be written or made."""
    unique = new_session_id()[-5:].lower()  # a ULID's last characters are random
    path = out or RECORDINGS / f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}-{unique}.mcap"
    check_recording_path(path)
    return path


def check_recording_path(path: Path) -> None:
    """Raise OutputError (one line) unless a new recording can be made at ``path`` (its missing
    folders made): a name ending in ``.mcap``, nothing there, and the nearest existing folder
    above it writable."""
    if path.suffix != ".mcap":
        raise OutputError(
            f"{path}: a recording is an MCAP file, its name must end in .mcap"
            f" (e.g. {path.with_suffix('.mcap').name})"
        )
    try:
        check_new_file(path, create_folder=True)
    except NotADirectoryError:  # a file where one of its folders should be
        above = nearest_existing(path.parent)
        raise OutputError(f"{path}: {above} is not a folder") from None
