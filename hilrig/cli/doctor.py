"""``hilrig doctor``: is this machine fit to run the 1 kHz loop? Its settings and timing floor."""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.robot_options import PasswordFile, RobotHost, RobotUser, RtdeRate

if TYPE_CHECKING:
    from rich.console import Console

    from hilrig.machine import Floor, Setting

MAX_SECONDS = 3600.0
TARGET_MISSED_PCT = 0.01  # what hilrig aims at (README, Performance)
MARKS = {"ok": "[green]ok  [/]", "warn": "[bold yellow]warn[/]", "note": "[dim]note[/]"}


@app.command()
def doctor(
    seconds: Annotated[
        float,
        typer.Option(
            help="How long each timing test runs (a bare thread's wake-ups, then the pty); 0 "
            "reads the settings only."
        ),
    ] = 10.0,
    cpu: Annotated[
        int | None,
        typer.Option(help="Wake the test thread on this CPU alone, as hilrig record --cpu."),
    ] = None,
    port: Annotated[
        Path | None,
        typer.Option(
            help="The wrist F/T sensor's serial port to check too (a real rig's ft_wrist_port, "
            "e.g. /dev/ttyUSB0): access, driver, a USB adapter's latency timer."
        ),
    ] = None,
    robot: RobotHost = None,
    robot_rpc_port: Annotated[
        int, typer.Option(help="The controller's JSON-RPC port (with --robot).")
    ] = 30004,
    robot_rtde_port: Annotated[int, typer.Option(help="Its RTDE port (with --robot).")] = 30010,
    robot_user: RobotUser = "aubo",
    robot_password_file: PasswordFile = None,
    rtde_rate: RtdeRate = 500.0,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON document instead of the report.")
    ] = False,
) -> None:
    """Check this machine for the 1 kHz loop: its settings that cost deadlines and its own
    timing floor, measured without hilrig's loop.

    The settings (real-time scheduling, idle states, the kernel's preemption model, isolated
    CPUs, real-time throttling, the kernel's unbound workers, clock source, CPU frequency, a
    hypervisor; with --port, the sensor's serial port) each get ok, warn (with what to change)
    or note. Then a bare thread under the loop's settings wakes every 1 ms, and 1 kHz messages
    pass through a pty as the F/T sensor's do: what they lose, a session here loses too
    (docs/rig-timing.md). Waits while a session runs.

    With --robot HOST, first the AUBO controller: reachable, login, interface version, robot
    and safety mode, and the RTDE rate it achieves over 2 s (the arm does not move); exits 1
    when a session could not start there.
    """
    import json
    import threading

    from rich.console import Console

    from hilrig.cli.errors import print_waiting
    from hilrig.errors import HilrigError
    from hilrig.machine import measure_floor, port_settings, read_settings
    from hilrig.rig.machine_lock import one_session_at_a_time
    from hilrig.timing import check_cpu

    if not (math.isfinite(seconds) and 0.0 <= seconds <= MAX_SECONDS):
        raise HilrigError(f"--seconds {seconds:g}: must be within 0..{MAX_SECONDS:g}")
    if cpu is not None and cpu < 0:
        raise HilrigError(f"--cpu {cpu}: must be a CPU's number, 0 or more")
    check_cpu(cpu)
    console = Console(highlight=False)
    controller = None
    if robot is not None:
        from hilrig.cli.controller_check import check_robot

        controller = check_robot(
            console,
            robot,
            (robot_rpc_port, robot_rtde_port),
            robot_user,
            robot_password_file,
            rtde_rate,
            quiet=as_json,
        )
    settings = read_settings()
    if port is not None:
        settings += port_settings(port)
    if not as_json:
        _print_settings(console, settings)
    floor = None
    if seconds > 0:
        if not as_json:
            console.print(
                f"measuring the timing floor: {seconds:g} s of wake-ups, {seconds:g} s of the pty"
            )
        # a session running meanwhile would spoil the figures, and they its deadlines
        with one_session_at_a_time(threading.Event(), print_waiting):
            floor = measure_floor(seconds, cpu=cpu)
    if as_json:
        document = {
            "settings": [asdict(setting) for setting in settings],
            "floor": None if floor is None else _floor_record(floor),
            "controller": None if controller is None else controller,
        }
        typer.echo(json.dumps(document, indent=2))
    elif floor is not None:
        _print_floor(console, floor)
    if controller is not None and controller["problem"]:
        raise typer.Exit(1)


def _print_settings(console: Console, settings: list[Setting]) -> None:
    from rich.markup import escape

    console.print("[bold]settings[/]")
    for setting in settings:
        note = f" - {escape(setting.note)}" if setting.note else ""
        console.print(f"  {MARKS[setting.verdict]}  {setting.name}: {escape(setting.value)}{note}")


def _print_floor(console: Console, floor: Floor) -> None:
    from rich.table import Table

    where = "" if floor.cpu is None else f" on CPU {floor.cpu}"
    policy = "SCHED_FIFO" if floor.sched_fifo else "normal priority"
    table = Table(title=f"timing floor ({floor.seconds:g} s each)", title_justify="left")
    table.add_column("")
    for column in ("count", "p50 us", "p99 us", "max us", "over 1 ms, %"):
        table.add_column(column, justify="right")
    rows = (
        (f"a bare thread's wake-ups{where} ({policy})", floor.wake_ups),
        ("  the fixed work after each", floor.work),
        ("1 kHz messages through a pty", floor.pty),
    )
    for label, t in rows:
        over = f"{t.over_a_period_pct:.3f}"
        table.add_row(
            label, str(t.count), f"{t.p50_us:.0f}", f"{t.p99_us:.0f}", f"{t.max_us:.0f}", over
        )
    console.print(table)
    if not math.isnan(floor.steal_pct):
        console.print(f"the hypervisor's steal meanwhile: {floor.steal_pct:.2f} % of the CPU time")
    share = floor.missed_at_least_pct
    verdict = "[green]within[/]" if share <= TARGET_MISSED_PCT else "[bold yellow]over[/]"
    console.print(
        f"the machine alone spoiled {share:.3f} % of the periods: a session here now misses at "
        f"least about as many of its deadlines, {verdict} hilrig's target of "
        f"{TARGET_MISSED_PCT} %"
    )


def _floor_record(floor: Floor) -> dict[str, object]:
    record = asdict(floor)
    record["missed_at_least_pct"] = floor.missed_at_least_pct
    return record
