"""``hilrig rig serve``: the emulated rig as its own process, until Ctrl-C or SIGTERM."""

from pathlib import Path
from typing import Annotated

import typer

from hilrig.cli.app import Group, app
from hilrig.cli.options import SCENARIO_NAMES

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
    rate_hz: Annotated[
        float, typer.Option("--rate", help="Frame rate of both streams, Hz.")
    ] = 1000.0,
    port_path: Annotated[
        Path | None,
        typer.Option(help="Where to put the F/T sensor's serial port link (default: a temp dir)."),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the sensor and joint-torque noise.")] = 0,
) -> None:
    """Run the emulated AUBO-i5 and wrist F/T sensor; print their endpoints; stop on Ctrl-C.

    The rig's slot loop runs in this process's main thread (real-time priority where permitted).
    """
    import signal

    from rich.console import Console

    from hilrig.emulator.rig import EmulatedRig, RigConfig
    from hilrig.emulator.scenarios import scenario

    console = Console(soft_wrap=True, highlight=False)  # endpoint lines: never wrapped
    config = RigConfig(rate_hz=rate_hz, seed=seed)
    rig = EmulatedRig(scenario(volunteer), config=config, port_path=port_path)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: rig.request_stop())
    endpoints = rig.open()
    try:
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
