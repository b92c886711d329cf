"""``hilrig demo``: the main job on the emulated rig, start to finish.

It joins every application (paper, rig, replay, analysis, viewer), so it lives at the top.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.app import app
from hilrig.errors import HilrigError

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from hilrig.rig import SessionResult

#: A pseudonym reserved for demonstrations.
DEMO_SUBJECT = "D001"
#: The laws each session is replayed through, compared against the baseline.
LAWS = ("adaptive", "variable-stiffness", "fixed")
BASELINE = "fixed"
#: A session's outputs, by suffix of its scenario's name; none is ever overwritten.
OUTPUTS = (".mcap", "-replay.parquet", ".rrd")


@dataclass(frozen=True)
class DemoSession:
    """One recorded collision: the volunteer scenario, the task, how long (s)."""

    scenario: str
    trajectory: str
    duration_s: float


#: Each collision ends about 2 s before its session.
SESSIONS = (
    DemoSession("paper-end-effector", "circle", 8.0),
    DemoSession("paper-body", "square", 7.5),
)


@app.command()
def demo(
    out: Annotated[
        Path,
        typer.Option(
            help="Directory for the paper tables and recordings (made if needed; nothing in it "
            "is ever overwritten)."
        ),
    ] = Path("build/demo"),
) -> None:
    """The paper's simulations, then its end-effector and body collisions on the emulated rig,
    each replayed through the three laws, compared, and saved as a Rerun view (.rrd); last, a
    small study (4 volunteers x 2 controllers) and its HTML report."""
    from rich.console import Console
    from rich.text import Text

    from hilrig.cli.demo_study import run_study
    from hilrig.cli.paper import ELSEWHERE, check_outputs
    from hilrig.cli.session_output import print_result
    from hilrig.errors import DiskError, OutputError
    from hilrig.paper.report import rich_table
    from hilrig.paper.reproduce import reproduce

    console = Console(soft_wrap=True)
    if not console.is_terminal:  # keep whole table rows when piped
        console = Console(soft_wrap=True, width=160)
    try:
        check_outputs(outputs(out))  # every output, before any work
        reproduction = reproduce(out / "paper")
    except DiskError:  # says what to do itself
        raise
    except OutputError as err:
        err.add_note(ELSEWHERE)
        raise
    console.print(rich_table(reproduction.sections[0], console.width))
    console.print(f"paper tables and figures in {out / 'paper'}\n", markup=False, highlight=False)
    peaks: dict[str, list[float]] = {}
    for session in SESSIONS:
        about = f" ({session.trajectory} task, {session.duration_s:g} s)"
        console.print(Text.assemble((f"session {session.scenario}", "bold"), about))
        result = record(session, out)
        print_result(console, result)
        problem = "; ".join(filter(None, (result.fault, result.recorder_error)))
        if problem:
            raise HilrigError(f"session {session.scenario} ended early: {problem}")
        peaks[session.scenario] = peak_offsets(result.path)
        compare_and_view(console, result.path)
    console.print(peaks_table(peaks))
    run_study(console, out)


def outputs(out: Path) -> list[Path]:
    """Every file the demo writes into ``out``."""
    from hilrig.cli.demo_study import study_outputs
    from hilrig.paper.reproduce import output_names

    paths = [out / "paper" / name for name in output_names()]
    paths += [out / f"{s.scenario}{suffix}" for s in SESSIONS for suffix in OUTPUTS]
    return paths + study_outputs(out)


def record(session: DemoSession, out: Path) -> SessionResult:
    """``session`` recorded on the emulated rig to ``out/<scenario>.mcap``; Ctrl-C or SIGTERM
    ends it cleanly (the recording is kept), then the demo stops (KeyboardInterrupt)."""
    import signal

    from hilrig.cli.errors import print_waiting
    from hilrig.recording.session_ids import new_session_id
    from hilrig.rig import LoopConfig, SessionConfig, record_session
    from hilrig.rig.stop import SessionStop

    config = SessionConfig(
        out=out / f"{session.scenario}.mcap",
        subject_id=DEMO_SUBJECT,
        scenario=session.scenario,
        trajectory=session.trajectory,
        duration_s=session.duration_s,
        loop=LoopConfig(),
        session_id=new_session_id(),
    )
    stop = SessionStop()  # says which signal ended the session: its file's ended_by
    before = {s: signal.signal(s, stop.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        result = record_session(config, stop=stop, on_wait=print_waiting)
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
    if stop.is_set():
        raise KeyboardInterrupt
    return result


def compare_and_view(console: Console, session: Path) -> None:
    """Replay ``session`` through LAWS, print their comparison against BASELINE, save the
    results beside it as ``<stem>-replay.parquet`` and its view as ``<stem>.rrd`` (both or
    neither)."""
    from hilrig.analysis import DEFAULT_EVENTS, analyze, load_replay
    from hilrig.cli.analyze import print_source
    from hilrig.outputs import new_files
    from hilrig.replay import parse_specs, run, write_parquet
    from hilrig.viz import save_rrd, scene_from_session

    specs = parse_specs(list(LAWS))
    replayed = session.with_name(f"{session.stem}-replay.parquet")
    view = session.with_suffix(".rrd")
    with new_files(replayed, view) as (replayed_tmp, view_tmp):
        write_parquet(run(session, specs), replayed_tmp)
        save_rrd(scene_from_session(session, specs), view_tmp)
    print_source(console, analyze(load_replay(replayed)), BASELINE, DEFAULT_EVENTS.delta)
    console.print(
        f"replays in {replayed}; view: rerun {view}  (or: hilrig view {session} -c ...)\n",
        markup=False,
        highlight=False,
    )


def peak_offsets(path: Path) -> list[float]:
    """The largest |offset| per axis (AXIS_NAMES order) recorded on /controller/state, m or rad."""
    import numpy as np

    from hilrig.recording import load
    from hilrig.rig import AXIS_NAMES

    state = load(path, topics=["/controller/state"])["/controller/state"]
    return [float(np.abs(state[f"offset_{i}"]).max()) for i in range(len(AXIS_NAMES))]


def peaks_table(peaks: dict[str, list[float]]) -> Table:
    """The largest offset per axis (rows) of each session (columns), mm and mrad."""
    from rich.table import Table

    from hilrig.rig import AXIS_NAMES

    table = Table(title="recorded sessions: largest offset per axis")
    table.add_column("axis")
    for scenario in peaks:
        table.add_column(scenario, justify="right")
    for i, name in enumerate(AXIS_NAMES):
        unit = "mm" if i < 3 else "mrad"
        table.add_row(f"{name} ({unit})", *(f"{1000 * p[i]:.1f}" for p in peaks.values()))
    return table
