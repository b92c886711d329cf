"""``hilrig view``: a session and its replays side by side in the Rerun viewer."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.errors import one_line_errors
from hilrig.cli.options import DEFAULT_MAX_POINTS, DEFAULT_MAX_POSES, GRPC_PORT, WEB_PORT
from hilrig.rerun_logs import rerun_logs_off

#: Seconds a viewer may take to receive the whole view before the command gives up.
FLUSH_S = 120.0
#: Seconds between two looks at the web server while serving (a Ctrl-C ends the wait at once).
POLL_S = 0.5

if TYPE_CHECKING:
    from rerun import RecordingStream
    from rich.console import Console

    from hilrig.viz import Scene, Sink, ViewReport


@app.command("view")
@one_line_errors
def view_command(
    file: Annotated[Path, typer.Argument(help="A recorded session (.mcap).", show_default=False)],
    controller: Annotated[
        list[str] | None,
        typer.Option(
            "--controller",
            "-c",
            help="Replay the session's input through this controller too: LAW or NAME=LAW "
            "(adaptive, variable-stiffness, fixed). Repeatable.",
        ),
    ] = None,
    setting: Annotated[
        list[str] | None,
        typer.Option("--set", help="NAME.[GROUP.]PARAM=VALUE for a --controller (repeatable)."),
    ] = None,
    results: Annotated[
        list[Path] | None,
        typer.Option(
            "--results",
            "-r",
            help="Show the runs of a replay result of FILE too (hilrig replay FILE --out "
            "X.parquet). Repeatable.",
        ),
    ] = None,
    save: Annotated[
        Path | None,
        typer.Option(
            help="Write the view to this new .rrd file instead of showing it (an existing file "
            "is refused unless --overwrite)."
        ),
    ] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing --save file.")] = False,
    web: Annotated[
        bool,
        typer.Option(
            help="Serve the web viewer on 127.0.0.1 (--web-port) until Ctrl-C, instead of "
            "spawning the desktop viewer."
        ),
    ] = False,
    connect: Annotated[
        str | None,
        typer.Option(
            help="Stream to a running viewer or server, e.g. rerun+http://127.0.0.1:9876/proxy "
            "(it must answer as a Rerun server within 3 s)."
        ),
    ] = None,
    port: Annotated[
        int, typer.Option(min=1, max=65535, help="Viewer gRPC port (desktop and web).")
    ] = GRPC_PORT,
    web_port: Annotated[
        int, typer.Option(min=1, max=65535, help="Web viewer HTTP port (--web).")
    ] = WEB_PORT,
    max_points: Annotated[
        int,
        typer.Option(
            min=0,
            help="Display at most this many points per time series (min/max per "
            "bucket); 0 shows every sample. The data is never changed.",
        ),
    ] = DEFAULT_MAX_POINTS,
    max_poses: Annotated[
        int,
        typer.Option(min=0, help="Robot poses and force arrows in 3D at most (0: every tick)."),
    ] = DEFAULT_MAX_POSES,
) -> None:
    """Show FILE (robot, end trajectories, forces, offsets, b, k, zeta, contact, events) and
    its replays through --controller runs, one colour per controller in every view."""
    from rich.console import Console
    from rich.text import Text

    from hilrig.errors import ViewError
    from hilrig.outputs import new_files
    from hilrig.replay import parse_specs

    with rerun_logs_off():
        from hilrig.viz import save_rrd, scene_from_session

    sink = _sink(save, overwrite, web, connect, port, web_port)
    console = Console(highlight=False, soft_wrap=True, markup=False)
    specs = parse_specs(controller or [], setting or [], []) if controller else []
    if setting and not controller:
        raise ViewError("--set changes a --controller: name one")
    scene = scene_from_session(file, specs, results or [])
    warnings = Console(stderr=True, highlight=False, soft_wrap=True, markup=False)
    for note in scene.notes:
        warnings.print(Text.assemble(("warning: ", "yellow"), note))
    if save is None:
        _show(console, sink, scene, max_points, max_poses)
        return
    with new_files(save, overwrite=overwrite) as (temporary,):  # whole, or nothing left
        report = save_rrd(scene, temporary, max_points=max_points, max_poses=max_poses)
    _print_report(console, report, scene.source)
    console.print(f"wrote {save}", markup=False, soft_wrap=True)


def _show(console: Console, sink: Sink, scene: Scene, max_points: int, max_poses: int) -> None:
    """Send ``scene`` to ``sink`` and wait until it has left (a web viewer: until Ctrl-C)."""
    from hilrig.viz import layout, open_stream, recording_id, show_scene

    rec, server = open_stream(sink, layout(scene, max_points), recording_id=recording_id(scene))
    try:
        report = show_scene(rec, scene, max_points=max_points, max_poses=max_poses)
        _flush(rec, sink)
        _print_report(console, report, scene.source)
        if server is not None:
            url = server.url
            _wait_for_interrupt(
                lambda: console.print(f"web viewer: {url}  (Ctrl-C to stop)"), server.exited
            )
    finally:
        try:
            rec.disconnect()  # a file is finished (and closed) here; before its server ends
        finally:
            if server is not None:
                server.close()


def _sink(
    save: Path | None, overwrite: bool, web: bool, connect: str | None, port: int, web_port: int
) -> Sink:
    """The one destination asked for; checked before anything is read."""
    from hilrig.errors import OutputError, ViewError
    from hilrig.outputs import check_new_file
    from hilrig.viz.sinks import Sink, SinkKind, check_reachable, check_rrd_path

    chosen = [name for name, on in (("--save", save), ("--web", web), ("--connect", connect)) if on]
    if len(chosen) > 1:
        raise ViewError(f"{' and '.join(chosen)}: choose one destination")
    if overwrite and save is None:
        raise ViewError("--overwrite replaces a --save file: name one")
    if save is not None:
        check_new_file(check_rrd_path(save, "--save"), overwrite=True)  # a regular file at most
        if not overwrite and save.exists():
            raise OutputError(f"{save}: already exists; pass --overwrite to replace it")
        return Sink(SinkKind.SAVE, path=save)
    if connect is not None:
        check_reachable(connect, "--connect")  # at once: Rerun would retry for minutes
        return Sink(SinkKind.CONNECT, url=connect)
    if web:
        if port == web_port:
            raise ViewError(f"--port and --web-port are both {port}: they must differ")
        return Sink(SinkKind.WEB, port=port, web_port=web_port)
    return Sink(SinkKind.SPAWN, port=port)


def _flush(rec: RecordingStream, sink: Sink) -> None:
    """Wait until the view has left, for FLUSH_S at most (a viewer that went away is one
    line)."""
    from hilrig.errors import ViewError

    try:
        rec.flush(timeout_sec=FLUSH_S)
    except Exception as err:  # Rerun's own error type for a viewer that does not take data
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        where = sink.url or f"port {sink.port}"
        raise ViewError(f"the viewer at {where} did not take the view ({first})") from err


def _print_report(console: Console, report: ViewReport, source: str) -> None:
    from rich.text import Text

    console.print(f"{source}: {len(report.runs)} run(s)")
    for label, color in report.runs:
        console.print(Text.assemble(("  ■ ", color), label))
    series = report.logged.series
    if series.active:
        console.print(
            f"display decimated: at most {series.points} of {series.samples} samples per "
            "series (min/max per bucket); the file is untouched"
        )


def _wait_for_interrupt(announce: Callable[[], None], gone: Callable[[], str] = str) -> None:
    """Block until Ctrl-C or SIGTERM; ``announce()`` once they are caught (a Ctrl-C right after
    the announcement ends the wait, it does not interrupt what comes before). ViewError when
    ``gone()`` says why what is served ended first (checked every :data:`POLL_S`)."""
    import signal
    import threading
    from types import FrameType

    from hilrig.errors import ViewError

    done = threading.Event()

    def stop(signum: int, frame: FrameType | None) -> None:
        done.set()

    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        announce()
        while not done.wait(POLL_S):
            if problem := gone():
                raise ViewError(problem)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
