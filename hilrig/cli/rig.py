"""``hilrig rig serve``: the emulated rig as its own process, until Ctrl-C or SIGTERM."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import Group, app
from hilrig.cli.options import SCENARIO_NAMES

if TYPE_CHECKING:
    from hilrig.emulator.rig import RigEndpoints

rig_app = typer.Typer(
    cls=Group, help="The emulated rig (devices behind their real wire protocols)."
)
app.add_typer(rig_app, name="rig")


@rig_app.command()
def serve(
    volunteer: Annotated[
        str,
        typer.Option("--scenario", help=f"Volunteer model: {', '.join(SCENARIO_NAMES)}."),
    ] = "paper-end-effector",
    scenario_set: Annotated[
        list[str] | None,
        typer.Option(
            "--scenario-set",
            metavar="KEY=VALUE",
            help="A setting of the scenario (repeatable; as hilrig record --scenario-set).",
        ),
    ] = None,
    rate_hz: Annotated[
        float, typer.Option("--rate", help="Frame rate of both streams, Hz (1 to 10000).")
    ] = 1000.0,
    port_path: Annotated[
        Path | None,
        typer.Option(help="Where to put the F/T sensor's serial port link (default: a temp dir)."),
    ] = None,
    seed: Annotated[
        int, typer.Option(min=0, help="Seed of the sensor and joint-torque noise.")
    ] = 0,
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print the endpoints as one JSON object on stdout (ft_wrist_port, aubo_rpc, "
            "aubo_rtde, robot_state, modbus as host:port), the rest on stderr.",
        ),
    ] = False,
) -> None:
    """Run the emulated AUBO-i5 (an ARCS controller: JSON-RPC and RTDE, and the Modbus pair) and
    wrist F/T sensor; print their endpoints; stop on Ctrl-C.

    The rig's slot loop runs in this process's main thread (real-time priority where permitted).
    Its controller's user is aubo, password 123456 (as a new AUBO controller's). The
    volunteer's clock starts when a client first enters servo mode (a session's start).
    """
    import math
    import signal

    from rich.console import Console

    from hilrig.cli.record import key_values
    from hilrig.emulator.rig import EmulatedRig, RigConfig
    from hilrig.errors import HilrigError
    from hilrig.world.scenarios import scenario

    volunteer_model = scenario(volunteer, key_values(scenario_set or []))
    if not (math.isfinite(rate_hz) and 1.0 <= rate_hz <= 10_000.0):
        raise HilrigError(f"--rate {rate_hz:g}: must be within 1..10000 Hz")
    if port_path is not None:
        check_port_folder(port_path)
    # endpoint lines: never wrapped, a path shown as it is (no markup)
    console = Console(soft_wrap=True, highlight=False, markup=False, stderr=as_json)
    # the volunteer's clock starts with a session's servo mode, as it does with a session's
    # own rig: its collision comes at the same time into the session
    config = RigConfig(
        rate_hz=rate_hz,
        seed=seed,
        scenario_starts_at_open=False,
        scenario_starts_with_servo=True,
    )
    rig = EmulatedRig(volunteer_model, config=config, port_path=port_path)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: rig.request_stop())
    endpoints = rig.open()
    try:
        if as_json:
            print(endpoints_json(endpoints), flush=True)
        console.print(f"emulated rig running, scenario {volunteer}, {rate_hz:g} Hz")
        for line in endpoints.lines():
            console.print(f"  {line}")
        console.print("Ctrl-C to stop")
        console.file.flush()  # a script reading the endpoints from a pipe must get them now
        rig.run()
    finally:
        rig.close()
    counts = rig.counters()
    console.print(
        f"stopped: {counts.ft_frames_sent} F/T frames, {counts.joint_frames_sent} joint-state "
        f"frames, {counts.modbus_writes} target writes, {counts.slots_late} late slots, "
        f"{counts.slots_skipped} skipped"
    )


def endpoints_json(endpoints: RigEndpoints) -> str:
    """The endpoints as one line of JSON: the port's path, each socket as ``host:port``."""
    import json

    sockets = {
        "aubo_rpc": endpoints.aubo_rpc,
        "aubo_rtde": endpoints.aubo_rtde,
        "robot_state": endpoints.robot_state,
        "modbus": endpoints.modbus,
    }
    return json.dumps(
        {
            "ft_wrist_port": endpoints.ft_wrist_port,
            **{name: f"{host}:{port}" for name, (host, port) in sockets.items() if host},
        }
    )


def check_port_folder(path: Path) -> None:
    """Raise OutputError unless the sensor's port link can be made in ``path``'s folder (what is
    at ``path`` itself the emulator checks: it never replaces anything)."""
    import os

    from hilrig.errors import OutputError

    folder = path.parent
    if not folder.exists():
        raise OutputError(f"--port-path {path}: folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputError(f"--port-path {path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"--port-path {path}: folder {folder} is not writable")
