"""``hilrig demo``: the main job on the emulated rig, start to finish."""

import threading
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from hilrig.analysis import DEFAULT_EVENTS, analyze, load_replay
from hilrig.cli.analyze import print_source
from hilrig.cli.app import app
from hilrig.cli.record import print_result
from hilrig.paper.report import rich_table
from hilrig.paper.reproduce import reproduce
from hilrig.recording import load
from hilrig.replay import parse_specs, run, write_parquet
from hilrig.rig.loop import LoopConfig
from hilrig.rig.records import AXIS_NAMES
from hilrig.rig.session import SessionConfig, record_session
from hilrig.viz import save_rrd, scene_from_session

DEMO_SUBJECT = "D001"  # a pseudonym reserved for demonstrations
SESSIONS = (  # (scenario, trajectory, seconds): each collision ends ~2 s before the session
    ("paper-end-effector", "circle", 8.0),
    ("paper-body", "square", 7.5),
)
LAWS = ("adaptive", "variable-stiffness", "fixed")  # compared, against fixed
OUTPUTS = (".mcap", "-replay.parquet", ".rrd")  # per session, replaced by a new demo


def peak_offsets(path: Path) -> list[float]:
    """The largest |offset| per axis (AXIS_NAMES order) recorded on /controller/state, m or rad."""
    state = load(path, topics=["/controller/state"])["/controller/state"]
    return [float(np.abs(state[f"offset_{i}"]).max()) for i in range(len(AXIS_NAMES))]


@app.command()
def demo(
    out: Annotated[Path, typer.Option(help="Directory for the paper tables and recordings.")] = (
        Path("build/demo")
    ),
) -> None:
    """The paper's simulations, then its end-effector and body collisions on the emulated rig,
    each replayed through the three laws, compared, and saved as a Rerun view (.rrd)."""
    console = Console(soft_wrap=True)
    if not console.is_terminal:  # keep whole table rows when piped
        console = Console(soft_wrap=True, width=160)
    for scenario, _, _ in SESSIONS:  # a new demo replaces its own earlier outputs
        for suffix in OUTPUTS:
            (out / f"{scenario}{suffix}").unlink(missing_ok=True)
    reproduction = reproduce(out / "paper")
    console.print(rich_table(reproduction.sections[0]))
    console.print(f"paper tables and figures in {out / 'paper'}\n", highlight=False)
    peaks: dict[str, list[float]] = {}
    for scenario, trajectory, seconds in SESSIONS:
        console.print(f"[bold]session {scenario}[/] ({trajectory} task, {seconds:g} s)")
        result = record_session(
            SessionConfig(
                out=out / f"{scenario}.mcap",
                subject_id=DEMO_SUBJECT,
                scenario=scenario,
                trajectory=trajectory,
                duration_s=seconds,
                loop=LoopConfig(),
                session_id=f"demo-{scenario}",
            ),
            stop=threading.Event(),
        )
        print_result(console, result)
        peaks[scenario] = peak_offsets(result.path)
        compare_and_view(console, result.path, out / f"{scenario}-replay.parquet")
    table = Table(title="recorded sessions: largest offset per axis")
    table.add_column("axis")
    for scenario in peaks:
        table.add_column(scenario, justify="right")
    for i, name in enumerate(AXIS_NAMES):
        unit = "mm" if i < 3 else "mrad"
        table.add_row(f"{name} ({unit})", *(f"{1000 * p[i]:.1f}" for p in peaks.values()))
    console.print(table)


def compare_and_view(console: Console, session: Path, replayed: Path) -> None:
    """Replay ``session`` through the three laws, print their comparison against fixed, save
    the results beside it and its view as ``<session>.rrd``."""
    specs = parse_specs(list(LAWS))
    write_parquet(run(session, specs), replayed)
    print_source(console, analyze(load_replay(replayed)), "fixed", DEFAULT_EVENTS.delta)
    view = session.with_suffix(".rrd")
    save_rrd(scene_from_session(session, specs), view)
    console.print(
        f"replays in {replayed}; view: rerun {view}  (or: hilrig view {session} -c ...)\n"
    )
