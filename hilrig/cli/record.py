"""``hilrig record``: run and record one volunteer collision session."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.options import GRPC_PORT, SCENARIO_NAMES, SCENARIO_SETTINGS_HELP, LawOption
from hilrig.cli.robot_options import (
    PasswordFile,
    RobotHost,
    RobotLinkOption,
    RobotUser,
    RtdeRate,
    ServoGain,
    ServoLookahead,
    ServoRate,
)
from hilrig.rig.kinds import RigKind, RobotLinkKind

if TYPE_CHECKING:
    from hilrig.rig import SessionConfig
    from hilrig.viz.live import LiveView
    from hilrig.viz.sinks import Sink

#: The longest session without --long (24 h).
LONG_SESSION_S = 86_400.0


@app.command()
def record(
    subject: Annotated[
        str, typer.Option(help="Pseudonymous subject id like S012 (names are refused).")
    ],
    rig: Annotated[
        RigKind, typer.Option(help="emulated (started here) or aubo (a real AUBO-i5).")
    ] = RigKind.EMULATED,
    robot: RobotHost = None,
    robot_link: RobotLinkOption = RobotLinkKind.ARCS,
    robot_user: RobotUser = "aubo",
    robot_password_file: PasswordFile = None,
    servo_rate: ServoRate = 200.0,
    servo_lookahead: ServoLookahead = 0.05,
    servo_gain: ServoGain = 200.0,
    rtde_rate: RtdeRate = 500.0,
    config: Annotated[
        Path | None,
        typer.Option(
            help="TOML: \\[endpoints] of a real rig (ft_wrist_port = '/dev/ttyUSB0'; with "
            "--robot-link modbus robot_state = 'host:8002', modbus = 'host:502'), \\[robot] (host, "
            "rpc_port, rtde_port of the AUBO controller) and/or \\[trajectory] (name = "
            "'waypoints', points = \\[\\[t_s, dx_m, dy_m, dz_m], ...], or another trajectory's "
            "options) and/or \\[scenario] (name = 'hand-contact' and its settings, e.g. "
            "stiffness_n_m = 800)."
        ),
    ] = None,
    controller: Annotated[LawOption, typer.Option(help="The admittance law.")] = LawOption.ADAPTIVE,
    params: Annotated[str, typer.Option(help="Preset of the Cartesian axes.")] = "adaptive",
    joint_params: Annotated[str, typer.Option(help="Preset of the joints.")] = "adaptive-joint",
    scenario: Annotated[
        str | None,
        typer.Option(
            help=f"Volunteer model (emulated rig): {', '.join(SCENARIO_NAMES)} (default"
            " paper-end-effector, or the config's \\[scenario] name)."
        ),
    ] = None,
    scenario_set: Annotated[
        list[str] | None,
        typer.Option(
            "--scenario-set",
            metavar="KEY=VALUE",
            help="A setting of the scenario (repeatable; over the config's \\[scenario] values);"
            f" vectors as x,y,z, none for no period. {SCENARIO_SETTINGS_HELP}",
        ),
    ] = None,
    trajectory: Annotated[
        str, typer.Option(help="Task: circle, square, waypoints (points from --config), hold.")
    ] = "circle",
    body_region: Annotated[
        str | None,
        typer.Option(
            help="The ISO/TS 15066 body region the robot meets, for the safety verdicts: skull, "
            "face, neck, back, chest, abdomen, pelvis, upper-arm, lower-arm, hand, thigh, "
            "lower-leg (default: the scenario's, hand for hand-contact and paper-end-effector).",
        ),
    ] = None,
    contact_area_cm2: Annotated[
        float | None,
        typer.Option(
            "--contact-area-cm2",
            help="The contact's area, cm^2 (default: the standard's probe, 1.96).",
        ),
    ] = None,
    duration: Annotated[
        float, typer.Option(help="Seconds (over 24 h with --long); Ctrl-C ends earlier, cleanly.")
    ] = 20.0,
    long: Annotated[
        bool, typer.Option("--long", help="Allow a --duration over 24 h (86400 s).")
    ] = False,
    rate: Annotated[float, typer.Option(help="Loop rate, Hz (the paper used 500).")] = 1000.0,
    cpu: Annotated[
        int | None,
        typer.Option(
            help="Run the loop's thread on this CPU alone, e.g. a core kept free for it "
            "(isolcpus); the rig's and recorder's processes stay where the OS puts them. "
            "Default: the OS places the thread too (docs/rig-timing.md, 'Placing the loop').",
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="The MCAP file to write (a new file, NAME.mcap).")
    ] = None,
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
        Path | None,
        typer.Option(
            help="Write the live view to this new .rrd file instead (an existing file is "
            "refused; it is moved into place, whole, when the session ends)."
        ),
    ] = None,
    view_port: Annotated[
        int,
        typer.Option(
            min=1,
            max=65535,
            help="With --view: the desktop viewer's gRPC port (a viewer already there is used).",
        ),
    ] = GRPC_PORT,
) -> None:
    """Run the admittance controller in the loop with the rig and record every stream."""
    import signal

    from hilrig.cli.errors import print_waiting, print_warning
    from hilrig.cli.robot_options import arcs_settings, real_endpoints
    from hilrig.cli.session_output import (
        SessionWatch,
        disk_failure_line,
        print_result,
        print_verdict,
        summary_console,
    )
    from hilrig.errors import DiskError, HilrigError
    from hilrig.recording.session_ids import new_session_id
    from hilrig.rig import LoopConfig, SessionConfig, record_session
    from hilrig.rig.config_file import RigFile, read_rig_file, session_path
    from hilrig.rig.stop import SessionStop

    if LONG_SESSION_S < duration < float("inf") and not long:  # inf: refused as not finite
        raise HilrigError(
            f"--duration {duration:g} s is over 24 h ({LONG_SESSION_S:g} s): give --long too"
            " for a session that long"
        )
    sink = view_sink(view, view_url, view_save, view_port)
    settings = read_rig_file(config) if config is not None else RigFile()
    endpoints = real_endpoints(settings, robot) if rig is RigKind.AUBO else None
    if rig is RigKind.EMULATED and robot is not None:
        raise HilrigError("--robot HOST is for --rig aubo (the emulated rig serves its own)")
    session = SessionConfig(
        out=session_path(out, subject),
        subject_id=subject,
        scenario=scenario or settings.scenario or "paper-end-effector",
        scenario_settings={**settings.scenario_settings, **key_values(scenario_set or [])},
        rig=rig,
        endpoints=endpoints,
        robot_link=robot_link,
        arcs=arcs_settings(
            emulated=rig is RigKind.EMULATED,
            user=robot_user,
            password_file=robot_password_file,
            servo_rate_hz=servo_rate,
            lookahead_s=servo_lookahead,
            gain=servo_gain,
            rtde_rate_hz=rtde_rate,
        ),
        duration_s=duration,
        trajectory=settings.trajectory or trajectory,
        trajectory_options=settings.trajectory_options,
        loop=LoopConfig(
            rate_hz=rate,
            law=controller.law(),
            cartesian_params=params,
            joint_params=joint_params,
            cpu=cpu,
        ),
        session_id=new_session_id(),
        body_region=body_region or "",
        contact_area_cm2=contact_area_cm2,
    )
    live = live_view(sink, session) if sink is not None else None
    stop = SessionStop()  # says which signal ended the session: the file's ended_by
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, stop.on_signal)
    with SessionWatch() as watch:
        result = record_session(
            session,
            stop=stop,
            live=live,
            on_start=watch.on_start,
            on_event=watch.on_event,
            on_wait=print_waiting,
            on_warning=print_warning,
        )
    print_result(summary_console(), result)
    print_verdict(summary_console(), result)
    if result.write_failure is not None:
        raise DiskError(disk_failure_line(result, result.write_failure, duration))
    if result.recorder_error:
        raise HilrigError(f"the recording is incomplete: {result.recorder_error}")
    if result.fault:
        raise HilrigError(f"the session ended early: {result.fault}; see {result.path}")


def key_values(items: list[str], option: str = "--scenario-set") -> dict[str, object]:
    """``KEY=VALUE`` texts as a dict (a later key wins); HilrigError (one line) otherwise."""
    from hilrig.errors import HilrigError

    values: dict[str, object] = {}
    for item in items:
        key, equals, value = item.partition("=")
        if not equals or not key.strip():
            raise HilrigError(f"{option} {item!r}: expected KEY=VALUE, e.g. stiffness_n_m=800")
        values[key.strip()] = value
    return values


def view_sink(
    view: bool, view_url: str | None, view_save: Path | None, view_port: int = GRPC_PORT
) -> Sink | None:
    """The live view's one destination (None: no live view), checked; raises HilrigError."""
    from hilrig.errors import HilrigError
    from hilrig.viz.live import check_sink
    from hilrig.viz.sinks import Sink, SinkKind, check_display

    options = (("--view", view), ("--view-url", view_url), ("--view-save", view_save))
    chosen = [name for name, given in options if given]
    if len(chosen) > 1:
        raise HilrigError(f"{' and '.join(chosen)}: choose one live view destination")
    if view_url is not None:
        sink = Sink(SinkKind.CONNECT, url=view_url)
    elif view_save is not None:
        sink = Sink(SinkKind.SAVE, path=view_save)
    elif view:
        sink = Sink(SinkKind.SPAWN, port=view_port)
        check_display(sink.port)  # at once, not when the viewer gives up
    else:
        return None
    check_sink(sink)
    return sink


def live_view(sink: Sink, session: SessionConfig) -> LiveView:
    """The live view of ``session`` (the robot's URDF, its controller and rate) at ``sink``."""
    from hilrig.robot import aubo_i5_urdf
    from hilrig.viz.live import LiveView

    return LiveView(
        sink,
        session_id=session.session_id,
        controller=session.loop.law.value,
        source=session.out.name,
        loop_rate_hz=session.loop.rate_hz,
        urdf=aubo_i5_urdf(),
    )
