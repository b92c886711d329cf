"""``hilrig replay``: recorded force traces through any controllers offline, ``--verify``, or
into a live rig (``--rig``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.cli.errors import one_line_errors
from hilrig.cli.options import ControllerOption, SetOption, SweepOption
from hilrig.rig.kinds import RigKind

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from hilrig.replay.job import Replayed
    from hilrig.world.contact import Mechanics

#: Inputs at least this large get a progress bar.
LONG_INPUT_BYTES = 16 << 20
#: Exit status of a failed --verify (2 is an error that stopped the command).
VERIFY_FAILED = 1


@app.command("replay")
@one_line_errors
def replay_command(
    file: Annotated[
        Path,
        typer.Argument(
            help="An MCAP session, or a CSV/Parquet table (t, fx fy fz, tau1..tau6).",
            show_default=False,
        ),
    ],
    controller: ControllerOption = None,
    setting: SetOption = None,
    sweep: SweepOption = None,
    out: Annotated[
        list[Path] | None,
        typer.Option(
            "--out", "-o", help="Write the results: .parquet (the table) or .mcap (topics)."
        ),
    ] = None,
    check: Annotated[
        bool,
        typer.Option(
            "--verify",
            help="Replay the session through its recorded controller and compare with the "
            "recorded state (exit 1 if anything differs by more than 1e-12).",
        ),
    ] = False,
    resample: Annotated[
        bool,
        typer.Option(help="Interpolate a table with non-uniform times onto a uniform grid."),
    ] = False,
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", "-j", min=1, help="Processes (default: chosen by size)."),
    ] = None,
    closed_loop: Annotated[
        bool,
        typer.Option(
            "--closed-loop",
            help="Predict the force each controller would have met (a recorded session only): "
            "fit each collision's contact and the arm's response, check that re-simulating the "
            "recorded controller reproduces its force, then simulate each controller with them "
            "(force_<axis> is the predicted force). Default: open loop, the recorded force "
            "replayed as it is whatever each controller does.",
        ),
    ] = False,
    contact_model: Annotated[
        str,
        typer.Option(
            "--contact-model",
            help="With --closed-loop: auto (the better fit; a force the robot's motion does "
            "not explain is a force source), spring-damper, hunt-crossley or force-source.",
        ),
    ] = "auto",
    rig: Annotated[
        RigKind | None,
        typer.Option(
            help="HIL replay: play the trace into a live rig (emulated, or aubo with --config) "
            "as a virtual collision and record the new session to --out."
        ),
    ] = None,
    subject: Annotated[
        str | None, typer.Option(help="HIL replay: pseudonymous subject id (default: FILE's).")
    ] = None,
    rate: Annotated[
        float | None, typer.Option(help="HIL replay: loop rate, Hz (default: 1000).")
    ] = None,
    start: Annotated[
        float | None, typer.Option(help="HIL replay: from this time of FILE, s (default: 0).")
    ] = None,
    duration: Annotated[
        float | None, typer.Option(help="HIL replay: this much of FILE, s (default: the rest).")
    ] = None,
    config: Annotated[
        Path | None, typer.Option(help="HIL replay on --rig aubo: TOML with \\[endpoints].")
    ] = None,
) -> None:
    """Replay FILE's force trace through controllers and sweeps; summarise the peak offsets."""
    from rich.console import Console

    from hilrig.errors import ReplayError

    console = Console(highlight=False)
    if not console.is_terminal:  # keep whole run names when piped
        console = Console(highlight=False, width=200)
    errors = Console(stderr=True, highlight=False, soft_wrap=True)
    long_input = file.is_file() and file.stat().st_size >= LONG_INPUT_BYTES
    rig_only: dict[str, object] = {"--subject": subject, "--rate": rate, "--start": start}
    rig_only |= {"--duration": duration, "--config": config}
    given = [option for option, value in rig_only.items() if value is not None]
    if rig is None and given:
        raise ReplayError(
            f"{', '.join(given)}: only for --rig (playing FILE into a live session); "
            "an offline replay or --verify takes the whole input"
        )
    mechanics = _mechanics(contact_model, closed_loop)
    if closed_loop and (check or rig is not None or resample or jobs):
        raise ReplayError(
            "--closed-loop simulates controllers offline on a recorded session: it takes no "
            "--verify, --rig, --resample or --jobs"
        )
    if check:
        if controller or setting or sweep or out or resample or jobs or rig is not None:
            raise ReplayError(
                "--verify replays the recorded controller: it takes no --controller, --set, "
                "--sweep, --out, --resample, --jobs or --rig"
            )
        _verify(file, console, errors, long_input=long_input)
    elif rig is not None:
        if controller or setting or sweep or resample or jobs:
            raise ReplayError(
                "--rig replays into the live loop's controller: it takes no --controller, --set, "
                "--sweep, --verify, --resample or --jobs"
            )
        timing = _rig_timing(rate, start, duration)
        _into_rig(file, rig, subject, timing, config, out or [])
    else:
        _offline(
            file,
            (controller or [], setting or [], sweep or []),
            out or [],
            console,
            errors,
            resample=resample,
            jobs=jobs,
            long_input=long_input,
            closed=(closed_loop, mechanics),
        )


def _mechanics(name: str, closed_loop: bool) -> Mechanics | None:
    """--contact-model as a Mechanics (None: auto); refused without --closed-loop."""
    from hilrig.errors import ReplayError
    from hilrig.world.contact import Mechanics

    if name != "auto" and not closed_loop:
        raise ReplayError(f"--contact-model {name}: only with --closed-loop")
    if name == "auto":
        return None
    try:
        return Mechanics(name)
    except ValueError:
        known = ", ".join(["auto", *(m.value for m in Mechanics)])
        raise ReplayError(f"--contact-model {name!r}: unknown; known: {known}") from None


def _verify(file: Path, console: Console, errors: Console, *, long_input: bool) -> None:
    """--verify: the recorded controller replayed and compared; exit 1 if anything differs."""
    from hilrig.cli.progress import phase_bar
    from hilrig.replay.verify import summary_lines, verify

    with phase_bar(errors, enabled=long_input) as progress:
        report = verify(file, progress=progress)
    for line in summary_lines(report):
        console.print(line, soft_wrap=True)
    if not report.ok:
        raise typer.Exit(VERIFY_FAILED)


def _rig_timing(
    rate: float | None, start: float | None, duration: float | None
) -> tuple[float, float, float | None]:
    """(rate Hz, start s, duration s or None) of a HIL replay, checked before any work."""
    import math

    from hilrig.errors import ReplayError

    rate_hz = 1000.0 if rate is None else rate
    start_s = 0.0 if start is None else start
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ReplayError(f"--rate {rate_hz:g}: the loop rate must be a finite number of Hz > 0")
    if not (math.isfinite(start_s) and start_s >= 0):
        raise ReplayError(f"--start {start_s:g}: must be a finite time of FILE >= 0 s")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise ReplayError(f"--duration {duration:g}: must be a finite time > 0 s")
    return rate_hz, start_s, duration


def _into_rig(
    file: Path,
    rig: RigKind,
    subject: str | None,
    timing: tuple[float, float, float | None],
    config: Path | None,
    out: list[Path],
) -> None:
    """--rig: FILE's trace as a virtual collision in a live session, recorded to --out."""
    import threading

    from rich.console import Console

    from hilrig.cli.errors import print_waiting, print_warning
    from hilrig.cli.session_output import print_result
    from hilrig.errors import ReplayError
    from hilrig.replay import load_trace
    from hilrig.replay.outputs import MCAP_SUFFIXES
    from hilrig.rig import VirtualInput, record_session
    from hilrig.rig.config_file import read_rig_file
    from hilrig.rig.playback import playback_session

    rate_hz, start_s, duration_s = timing
    if len(out) > 1 or (out and out[0].suffix.lower() not in MCAP_SUFFIXES):
        raise ReplayError("--rig records one new session: pass at most one --out FILE.mcap")
    trace = load_trace(file)
    virtual = VirtualInput.from_columns(
        trace.t_s, trace.columns, start_s=start_s, duration_s=duration_s
    )
    subject_id = subject or (trace.session.subject_id if trace.session is not None else None)
    if subject_id is None:
        raise ReplayError(f"{file}: no subject id in the file: pass --subject")
    session = playback_session(
        virtual,
        subject_id,
        source=f"{file} from {start_s} s for {virtual.duration_s:.3f} s",
        rig=rig,
        rate_hz=rate_hz,
        endpoints=read_rig_file(config).endpoints if config is not None else None,
        out=out[0] if out else None,
    )
    result = record_session(
        session, stop=threading.Event(), on_wait=print_waiting, on_warning=print_warning
    )
    print_result(Console(soft_wrap=True, highlight=False), result)
    if result.recorder_error:
        raise ReplayError(f"the recording is incomplete: {result.recorder_error}")


def _offline(
    file: Path,
    spec_options: tuple[list[str], list[str], list[str]],
    out: list[Path],
    console: Console,
    errors: Console,
    *,
    resample: bool,
    jobs: int | None,
    long_input: bool,
    closed: tuple[bool, Mechanics | None],
) -> None:
    """FILE's trace through the --controller, --set and --sweep runs, written to --out; closed
    loop with ``closed`` (on, contact model)."""
    from rich.text import Text

    from hilrig.cli.closed_loop import closed_summary
    from hilrig.cli.progress import phase_bar
    from hilrig.replay.job import (
        check_closed_input,
        closed_replay_file,
        replay_file,
        replay_outputs,
        write_outputs,
    )
    from hilrig.replay.specs import parse_specs

    specs = parse_specs(*spec_options)  # the size of sweeps is refused here, before any work
    closed_loop, mechanics = closed
    if closed_loop:
        check_closed_input(file)
    bar = long_input or (closed_loop and errors.is_terminal)
    with replay_outputs(out) as outputs, phase_bar(errors, enabled=bar) as progress:
        if closed_loop:
            replayed = closed_replay_file(file, specs, mechanics=mechanics, progress=progress)
        else:
            replayed = replay_file(file, specs, resample=resample, jobs=jobs, progress=progress)
        for note in replayed.trace.notes:
            errors.print(Text.assemble(("note: ", "yellow"), note))
        write_outputs(replayed, outputs, progress=progress)
    for path in out:  # all of them in place, or none
        console.print(f"wrote {path}", markup=False, soft_wrap=True)
    console.print(_summary(replayed))
    _print_verdicts(console, replayed)
    if closed_loop:
        for line in closed_summary(replayed):
            console.print(line, soft_wrap=True)
    else:
        console.print(
            "open loop: every controller met the recorded force as it was (a person is not a "
            "force source: --closed-loop predicts the force each would have met)",
            soft_wrap=True,
        )


def _print_verdicts(console: Console, replayed: Replayed) -> None:
    """Each run's safety verdict per collision against the recording's body region (on its
    predicted force, closed loop); nothing when the recording names no region."""
    session = replayed.trace.session
    if session is None or not session.body_region:
        return
    from hilrig.analysis import Source, SourceKind, analyze, runs_from_frame
    from hilrig.analysis.report import verdict_line, verdicts_table

    source = Source(
        Path(replayed.trace.source),
        SourceKind.REPLAY,
        runs_from_frame(replayed.table),
        body_region=session.body_region,
        contact_area_cm2=session.contact_area_cm2,
    )
    analysis = analyze(source)
    if analysis.verdicts:
        console.print(verdicts_table(analysis))
    console.print(verdict_line(analysis), soft_wrap=True)


def _summary(replayed: Replayed) -> Table:
    """Per run, the largest |offset| per axis: mm for x, y, z and mrad for joints."""
    from rich.table import Table

    trace, peaks = replayed.trace, replayed.peak_offsets()
    table = Table(
        title=f"max |offset| (x y z: mm, joints: mrad) over {trace.duration_s:.3f} s of "
        f"{trace.source}",
        title_justify="left",
    )
    table.add_column("run", overflow="fold")
    for axis in trace.axis_names:
        table.add_column(axis.replace("joint", "j"), justify="right")
    for run in replayed.runs:
        table.add_row(run.name, *(f"{1000 * peaks[run.name][a]:.2f}" for a in trace.axis_names))
    return table
