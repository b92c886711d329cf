"""``hilrig record``: run and record one volunteer collision session."""

import signal
import sys
import threading
import time
import tomllib
from collections import deque
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.text import Text

from hilrig.cli.app import app
from hilrig.control import Law
from hilrig.emulator.rig import RigEndpoints
from hilrig.emulator.scenarios import SCENARIOS
from hilrig.errors import HilrigError
from hilrig.recording.samples import EventRecord
from hilrig.rig import (
    ControlLoop,
    LoopConfig,
    RigKind,
    SessionConfig,
    SessionResult,
    record_session,
)
from hilrig.robot import aubo_i5_urdf
from hilrig.viz.live import LiveView, check_sink
from hilrig.viz.sinks import Sink, SinkKind


def read_config(path: Path) -> dict[str, Any]:
    """A session config file (TOML); raises HilrigError naming the file."""
    try:
        return tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise HilrigError(f"{path}: cannot read the config ({err})") from err


def endpoints_from_config(path: Path, config: dict[str, Any]) -> RigEndpoints:
    """The real rig's endpoints from the config's ``[endpoints]`` table."""
    try:
        table = config["endpoints"]
        robot_host, robot_port = str(table["robot_state"]).rsplit(":", 1)
        modbus_host, modbus_port = str(table["modbus"]).rsplit(":", 1)
        return RigEndpoints(
            str(table["ft_wrist_port"]),
            (robot_host, int(robot_port)),
            (modbus_host, int(modbus_port)),
        )
    except (KeyError, ValueError, TypeError) as err:
        raise HilrigError(f"{path}: no valid [endpoints] table ({err})") from err


def status_line(loop: ControlLoop, started: float) -> Text:
    """One line: time, tick rate, lateness, force, offset, contact, hold reason, drops."""
    s = loop.status
    elapsed = max(time.monotonic() - started, 1e-9)
    line = (
        f"{elapsed:6.1f} s  {s.ticks / elapsed:6.0f} Hz  late {s.lateness_us:5.0f} us  "
        f"|f| {s.force_n:5.1f} N  |e| {s.offset_mm:5.1f} mm  {s.contact:10s}"
    )
    if s.holding:
        line += f"  HOLD ({s.holding})"
    if s.drops:
        line += f"  drops {s.drops}"
    return Text(line)


def view_sink(view: bool, view_url: str | None, view_save: Path | None) -> Sink | None:
    """The live view's one destination (None: no live view), checked; raises HilrigError."""
    chosen = [
        n
        for n, on in (("--view", view), ("--view-url", view_url), ("--view-save", view_save))
        if on
    ]
    if len(chosen) > 1:
        raise HilrigError(f"{' and '.join(chosen)}: choose one live view destination")
    if view_url is not None:
        sink = Sink(SinkKind.CONNECT, url=view_url)
    elif view_save is not None:
        sink = Sink(SinkKind.SAVE, path=view_save)
    elif view:
        sink = Sink(SinkKind.SPAWN)
    else:
        return None
    check_sink(sink)
    return sink


def print_result(console: Console, result: SessionResult) -> None:
    summary = result.summary
    late = summary.lateness.summary_us()
    s2c = summary.sensor_to_command.summary_us()
    missed_pct = 100 * summary.missed_deadlines / max(summary.ticks, 1)
    console.print(f"recorded {result.path}", highlight=False)
    console.print(
        f"  {summary.ticks} ticks, missed deadlines {summary.missed_deadlines} "
        f"({missed_pct:.3f} %),"
        f" lateness p50 {late['p50']:.0f} us p99 {late['p99']:.0f} us max {late['max']:.0f} us",
        highlight=False,
    )
    ack = summary.sensor_to_ack.summary_us()
    console.print(
        f"  sensor-to-command (request sent) p50 {s2c['p50']:.0f} us p99 {s2c['p99']:.0f} us, "
        f"to its acknowledgement p50 {ack['p50']:.0f} us p99 {ack['p99']:.0f} us",
        highlight=False,
    )
    console.print(
        f"  {result.messages_written or 'unknown'} messages written, {result.drops} dropped; "
        f"{len(result.events)} events, {summary.hold_ticks} hold ticks",
        highlight=False,
    )
    rig = result.rig_counters
    if rig is not None:
        p50, p99, _ = rig.slot_lateness_us
        console.print(
            f"  emulated rig: {rig.ft_frames_sent} F/T frames and {rig.joint_frames_sent} joint "
            f"states sent, its own slots late p50 {p50:.0f} us p99 {p99:.0f} us",
            highlight=False,
        )
    if result.view is not None:
        view = result.view
        line = f"  live view: {view.shown} batches shown, {view.sent} sent, {view.dropped} dropped"
        console.print(line + (f"; {view.problem}" if view.problem else ""), highlight=False)


@app.command()
def record(
    subject: Annotated[
        str, typer.Option(help="Pseudonymous subject id like S012 (names are refused).")
    ],
    rig: Annotated[
        RigKind, typer.Option(help="emulated (started here) or aubo.")
    ] = RigKind.EMULATED,
    config: Annotated[
        Path | None,
        typer.Option(
            help="TOML: [endpoints] of a real rig (ft_wrist_port = '/dev/ttyUSB0', robot_state = "
            "'host:8002', modbus = 'host:502', RTU over TCP) and/or [trajectory] (name = "
            "'waypoints', points = [[t_s, dx_m, dy_m, dz_m], ...], or another trajectory's "
            "options)."
        ),
    ] = None,
    controller: Annotated[Law, typer.Option(help="The admittance law.")] = Law.ADAPTIVE,
    params: Annotated[str, typer.Option(help="Preset of the Cartesian axes.")] = "adaptive",
    joint_params: Annotated[str, typer.Option(help="Preset of the joints.")] = "adaptive-joint",
    scenario: Annotated[
        str, typer.Option(help=f"Volunteer model (emulated rig): {', '.join(sorted(SCENARIOS))}.")
    ] = "paper-end-effector",
    trajectory: Annotated[
        str, typer.Option(help="Task: circle, square, waypoints (points from --config), hold.")
    ] = "circle",
    duration: Annotated[float, typer.Option(help="Seconds; Ctrl-C ends earlier, cleanly.")] = 20.0,
    rate: Annotated[float, typer.Option(help="Loop rate, Hz (the paper used 500).")] = 1000.0,
    out: Annotated[Path | None, typer.Option(help="The MCAP file to write.")] = None,
    view: Annotated[
        bool,
        typer.Option(
            "--view",
            help="Show the session live in the Rerun desktop viewer, decimated to 50 Hz for "
            "display (the file keeps every sample).",
        ),
    ] = False,
    view_url: Annotated[
        str | None,
        typer.Option(
            help="Stream the live view to a running viewer or server instead, e.g. "
            "rerun+http://127.0.0.1:9876/proxy."
        ),
    ] = None,
    view_save: Annotated[
        Path | None, typer.Option(help="Write the live view to this .rrd file instead.")
    ] = None,
) -> None:
    """Run the admittance controller in the loop with the rig and record every stream."""
    console = Console(soft_wrap=True)
    if rig is RigKind.AUBO and config is None:
        raise HilrigError("--rig aubo needs --config with the rig's endpoints")
    sink = view_sink(view, view_url, view_save)
    settings = read_config(config) if config is not None else {}
    trajectory_options = dict(settings.get("trajectory", {}))
    trajectory = str(trajectory_options.pop("name", trajectory))
    path = out or Path("recordings") / f"{subject}-{time.strftime('%Y%m%d-%H%M%S')}.mcap"
    path.parent.mkdir(parents=True, exist_ok=True)
    session = SessionConfig(
        out=path,
        subject_id=subject,
        scenario=scenario,
        rig=rig,
        endpoints=(
            endpoints_from_config(config, settings)
            if config is not None and "endpoints" in settings
            else None
        ),
        duration_s=duration,
        trajectory=trajectory,
        trajectory_options=trajectory_options,
        loop=LoopConfig(
            rate_hz=rate, law=controller, cartesian_params=params, joint_params=joint_params
        ),
        session_id=time.strftime("%Y%m%d-%H%M%S"),
    )
    live = None
    if sink is not None:
        live = LiveView(
            sink,
            session_id=session.session_id,
            controller=session.loop.law.value,
            source=path.name,
            loop_rate_hz=session.loop.rate_hz,
            urdf=aubo_i5_urdf(),
        )
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    started = time.monotonic()
    loop_box: list[ControlLoop] = []
    pending: deque[tuple[float, EventRecord]] = deque()  # the tick appends, never prints
    done = threading.Event()
    show_status = sys.stderr.isatty()

    def print_progress() -> None:
        """Events as they come and, on a terminal, one status line twice a second."""
        while True:
            finished = done.wait(0.5)
            while pending:  # drained once more after the session ends: no event left unprinted
                t_s, record = pending.popleft()
                where = f" ({record.axis})" if record.axis else ""
                text = f"{t_s:7.2f} s  {record.kind.name.lower()}: {record.source}{where}"
                line = f"{text} {record.detail}".rstrip()
                sys.stderr.write(f"\r\033[K{line}\n" if show_status else f"{line}\n")
            if finished:
                return
            if show_status and loop_box:
                sys.stderr.write(f"\r\033[K{status_line(loop_box[0], started).plain}")
            sys.stderr.flush()

    def on_start(loop: ControlLoop) -> None:
        nonlocal started
        started = time.monotonic()
        loop_box.append(loop)

    printer = threading.Thread(target=print_progress, daemon=True, name="progress")
    printer.start()
    try:
        result = record_session(
            session,
            stop=stop,
            live=live,
            on_start=on_start,
            on_event=lambda r: pending.append((time.monotonic() - started, r)),
        )
    finally:
        done.set()
        printer.join(timeout=2)
        if show_status:
            sys.stderr.write("\r\033[K")
    print_result(console, result)
    if result.recorder_error:
        raise HilrigError(f"the recording is incomplete: {result.recorder_error}")
