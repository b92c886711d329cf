"""``hilrig study simulate``: a synthetic study recorded on the emulated rig, session by session."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hilrig.cli.options import SCENARIO_NAMES, SCENARIO_SETTINGS_HELP, LawOption
from hilrig.cli.study import study_app

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from hilrig.study.simulate import PlannedSession, SessionStep, StudyPlan

CONTROLLERS = ", ".join(law.value for law in LawOption)


@study_app.command("simulate")
def simulate(
    out: Annotated[
        Path,
        typer.Argument(
            metavar="DIR",
            help="The study's folder (made if needed): DIR/<subject>/<subject>-<controller>-"
            "<repetition>.mcap and the design in DIR/simulation.toml. Nothing in it is ever "
            "overwritten; running the command again records only the sessions still missing.",
        ),
    ],
    subjects: Annotated[
        int, typer.Option(help="How many volunteers (pseudonyms S001, S002, ...).")
    ],
    controllers: Annotated[
        str,
        typer.Option(help=f"The controllers each subject meets, comma-separated: {CONTROLLERS}."),
    ],
    repeats: Annotated[int, typer.Option(help="Sessions per subject and controller.")] = 1,
    scenario: Annotated[
        str, typer.Option(help=f"The volunteer model: {', '.join(SCENARIO_NAMES)}.")
    ] = "hand-contact",
    vary: Annotated[
        list[str] | None,
        typer.Option(
            metavar="NAME=LO..HI",
            help="A scenario setting drawn per subject, uniformly in [LO, HI] (repeatable).",
        ),
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            metavar="NAME=VALUE",
            help="A scenario setting fixed for every subject (repeatable); vectors as x,y,z, none"
            f" for no period. {SCENARIO_SETTINGS_HELP}",
        ),
    ] = None,
    duration_s: Annotated[
        float | None,
        typer.Option(
            "--duration-s",
            help="Seconds per session (default: the latest collision's end + 2 s of recovery; "
            "6.6 s for hand-contact's defaults).",
        ),
    ] = None,
    seed: Annotated[
        int, typer.Option(help="Fixes the plan: the settings drawn and the orders.")
    ] = 0,
    body_region: Annotated[
        str | None,
        typer.Option(
            help="The ISO/TS 15066 body region met, for the safety verdicts (default: the "
            "scenario's, hand for hand-contact)."
        ),
    ] = None,
) -> None:
    """Record a synthetic study on the emulated rig: each subject a volunteer
    model with its own settings, meeting each controller --repeats times in an
    order fixed by --seed (printed first), each session in real time."""
    import signal

    from hilrig.cli.errors import print_waiting
    from hilrig.cli.record import key_values
    from hilrig.cli.session_output import summary_console
    from hilrig.rig.stop import SessionStop
    from hilrig.study.simulate import (
        StudyDesign,
        parse_controllers,
        parse_range,
        plan_study,
        simulate_study,
    )

    design = StudyDesign(
        subjects=subjects,
        controllers=parse_controllers(controllers),
        repeats=repeats,
        scenario=scenario,
        vary=tuple(parse_range(text) for text in vary or []),
        fixed={key: str(value) for key, value in key_values(set_ or [], "--set").items()},
        duration_s=duration_s,
        seed=seed,
        body_region=body_region or "",
    )
    plan = plan_study(design)
    console = summary_console()
    console.print(plan_table(plan))
    stop = SessionStop()  # says which signal ended the session: its file's ended_by
    before = {s: signal.signal(s, stop.on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with SessionBar(console, len(plan.sessions)) as bar:
            run = simulate_study(
                plan,
                out,
                on_session=bar.step,
                on_begin=bar.begin,
                stop=stop,
                on_wait=print_waiting,
            )
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
    counts = {status: sum(s.status == status for s in run.steps) for status in STATUSES}
    done = ", ".join(f"{n} {STATUSES[status]}" for status, n in counts.items())
    console.print(f"{done}; the design is in {run.design_file}")
    if stop.is_set():
        last = [s for s in run.steps if s.status == "recorded"][-1:]
        for step in last:  # the session Ctrl-C ended: kept, never recorded over
            console.print(
                f"{out / step.session.file}: interrupted; kept (move it away to record it again)"
            )
        raise KeyboardInterrupt


#: What each status of a session is called in the last line.
STATUSES = {"recorded": "recorded", "done": "recorded before", "skipped": "skipped"}


class SessionBar:
    """A rich bar over the study's sessions (done/total) with a line per session above it."""

    def __init__(self, console: Console, total: int) -> None:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        self.total = total
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn())
        bar = Progress(*columns, console=console, transient=True, disable=not console.is_terminal)
        self.progress = bar
        self.task = self.progress.add_task("sessions", total=total)

    def __enter__(self) -> SessionBar:
        self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.progress.stop()

    def begin(self, index: int, planned: PlannedSession) -> None:
        self.progress.update(self.task, description=f"recording {planned.file.stem}")

    def step(self, step: SessionStep) -> None:
        """The session's line; the whole summary when it ended early (the study stops)."""
        from hilrig.cli.session_output import print_result

        console, result = self.progress.console, step.result
        console.print(session_line(step, self.total), markup=False)
        if result is not None and (result.fault or result.recorder_error):
            print_result(console, result)
        self.progress.advance(self.task)


def session_line(step: SessionStep, total: int) -> str:
    """One line: the session's place, name and what became of it (ticks, drops, hold ticks)."""
    head = f"{step.index + 1:>{len(str(total))}}/{total} {step.session.file.stem}"
    result = step.result
    if step.status == "done":
        return f"{head}: recorded before"
    if result is None:
        return f"{head}: skipped: {step.note}"
    summary = result.summary
    line = (
        f"{head}: {summary.ticks} ticks, {result.drops} dropped, {summary.hold_ticks} hold "
        f"ticks, {len(result.events)} events"
    )
    problem = "; ".join(filter(None, (result.fault, result.recorder_error)))
    return f"{line}; ended early: {problem}" if problem else line


def plan_table(plan: StudyPlan) -> Table:
    """The plan, a row per session in recording order: subject, controller, repetition, file
    and the subject's drawn settings."""
    from rich.table import Table

    design = plan.design
    table = Table(
        title=f"{len(plan.sessions)} sessions of {plan.duration_s:g} s, {design.scenario}, "
        f"seed {design.seed}"
    )
    for name in ("#", "subject", "controller", "rep", "file"):
        table.add_column(name, justify="right" if name in ("#", "rep") else "left")
    for span in design.vary:
        table.add_column(span.name, justify="right")
    drawn = {s.subject_id: s.drawn for s in plan.subjects}
    for number, session in enumerate(plan.sessions, start=1):
        values = [f"{drawn[session.subject_id][span.name]:.4g}" for span in design.vary]
        table.add_row(
            str(number),
            session.subject_id,
            session.controller,
            str(session.repetition),
            str(session.file),
            *values,
        )
    return table
