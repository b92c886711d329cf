"""A synthetic study recorded on the emulated rig: volunteers, controllers, repetitions.

The seed fixes the plan before anything is recorded (:func:`plan_study`): each subject (S001,
...) is a volunteer model with its varied settings drawn uniformly in their ranges (to 6
digits), meeting every controller ``repeats`` times in a counterbalanced order (a row of a
Latin square over the controllers, rows shuffled per block of as many subjects as controllers;
each repetition goes through the order). More subjects keep the first ones' draws.

:func:`simulate_study` records it in real time to ``DIR/<subject>/<subject>-<controller>-<rep>
.mcap`` and writes the design to ``DIR/simulation.toml``. Nothing is overwritten: a session
whose file exists is skipped (done if it is the plan's session, whole; else with a note), so
running the same plan again resumes it.
"""

from __future__ import annotations

import json
import math
import threading
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hilrig import __version__
from hilrig.control import Law
from hilrig.errors import HilrigError, ParameterError
from hilrig.outputs import new_files
from hilrig.paper.profiles import BODY_PROFILES, END_EFFECTOR_PROFILES
from hilrig.recording import inspect, validate_subject_id
from hilrig.recording.info import LOOP_TOPIC
from hilrig.rig import LoopConfig, SessionConfig, SessionResult, record_session
from hilrig.world.body import body_region as check_body_region
from hilrig.world.scenarios import Scenario, scenario, settings_fields, settings_of

RECOVERY_S = 2.0  # s recorded after the collision's end by default
SPAN_TOLERANCE_S = 0.05  # s: a whole session's ticks (LOOP_TOPIC) span its duration less this
DESIGN_FILE = "simulation.toml"
TRAJECTORY = "hold"  # the robot holds its pose, so every volunteer meets the tool
EXAMPLE = "e.g. stiffness_n_m=200..1000"
Order = tuple[str, ...]  # controllers, in the order a subject meets them


@dataclass(frozen=True)
class SettingRange:
    """A scenario setting drawn per subject, uniformly in [low, high]."""

    name: str
    low: float
    high: float


@dataclass(frozen=True)
class StudyDesign:
    """What ``hilrig study simulate`` was asked; ``fixed`` settings are text (as on the command
    line); ``duration_s`` None: long enough for the collisions (:func:`default_duration_s`)."""

    subjects: int
    controllers: tuple[str, ...]
    repeats: int = 1
    scenario: str = "hand-contact"
    vary: tuple[SettingRange, ...] = ()
    fixed: dict[str, str] = field(default_factory=dict)
    duration_s: float | None = None
    seed: int = 0
    body_region: str = ""

    def command(self) -> str:
        """The command line that plans this design again (DIR: the study's folder)."""
        words = ["hilrig study simulate DIR", f"--subjects {self.subjects}"]
        words += [f"--controllers {','.join(self.controllers)}", f"--repeats {self.repeats}"]
        words += [f"--scenario {self.scenario}", f"--seed {self.seed}"]
        words += [f"--vary {r.name}={r.low!r}..{r.high!r}" for r in self.vary]
        words += [f"--set {key}={value}" for key, value in self.fixed.items()]
        if self.duration_s is not None:
            words.append(f"--duration-s {self.duration_s!r}")
        if self.body_region:
            words.append(f"--body-region {self.body_region}")
        return " ".join(words)


@dataclass(frozen=True)
class SubjectPlan:
    """A volunteer: its pseudonym, the values drawn for it, all its scenario's settings (as the
    recording stores them) and its controllers' order."""

    subject_id: str
    drawn: dict[str, float]
    settings: dict[str, Any]
    order: tuple[str, ...]


@dataclass(frozen=True)
class PlannedSession:
    """One session of the plan; ``file`` is relative to the study's folder."""

    subject_id: str
    controller: str
    repetition: int  # 1, 2, ...
    settings: dict[str, Any]
    file: Path  # its stem is the session's id


@dataclass(frozen=True)
class StudyPlan:
    """The design, its subjects and its sessions in recording order, each ``duration_s`` long."""

    design: StudyDesign
    subjects: tuple[SubjectPlan, ...]
    sessions: tuple[PlannedSession, ...]
    duration_s: float


@dataclass(frozen=True)
class SessionStep:
    """A planned session ``recorded`` now, ``done`` before or ``skipped`` (``note``: why)."""

    index: int  # 0-based, in the plan's order
    session: PlannedSession
    status: str
    result: SessionResult | None = None
    note: str = ""


@dataclass(frozen=True)
class StudyRun:
    """What :func:`simulate_study` did: each session's step (plan order), the design's file."""

    steps: tuple[SessionStep, ...]
    design_file: Path


def parse_range(text: str) -> SettingRange:
    """``NAME=LO..HI`` as two numbers (:func:`check_design` checks them); ParameterError."""
    name, equals, span = text.partition("=")
    low_text, dots, high_text = span.partition("..")
    if not (equals and dots and name.strip()):
        raise ParameterError(f"--vary {text!r}: expected NAME=LO..HI, {EXAMPLE}")
    try:
        return SettingRange(name.strip(), float(low_text), float(high_text))
    except ValueError:
        raise ParameterError(f"--vary {text!r}: LO..HI must be two numbers, {EXAMPLE}") from None


def parse_controllers(text: str) -> tuple[str, ...]:
    """``adaptive,fixed`` as controller (law) names; ParameterError naming ``--controllers``."""
    names = tuple(name.strip() for name in text.split(","))
    known = [law.value for law in Law]
    for name in names:
        if name not in known:
            raise ParameterError(
                f"--controllers {text!r}: unknown controller {name!r}; known: {', '.join(known)}"
            )
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ParameterError(f"--controllers {text!r}: {', '.join(twice)} named twice")
    return names


def check_design(design: StudyDesign) -> None:
    """Raise ParameterError (one line naming the option and value) for anything that cannot be
    planned; the subjects' drawn settings are checked by :func:`plan_study`."""
    if design.subjects < 1:
        raise ParameterError(f"--subjects {design.subjects}: must be at least 1")
    if design.repeats < 1:
        raise ParameterError(f"--repeats {design.repeats}: must be at least 1")
    parse_controllers(",".join(design.controllers))
    if (duration := design.duration_s) is not None and not (0 < duration < math.inf):
        raise ParameterError(f"--duration-s {duration:g}: must be a finite number of seconds > 0")
    if design.seed < 0:
        raise ParameterError(f"--seed {design.seed}: must be an integer >= 0")
    if design.body_region:
        _named("--body-region", design.body_region, check_body_region, design.body_region)
    _named("--scenario", design.scenario, scenario, design.scenario)
    for key, value in design.fixed.items():
        _named("--set", f"{key}={value}", scenario, design.scenario, {key: value})
    fields = {f.name: str(f.type) for f in settings_fields(design.scenario)}
    seen: set[str] = set()
    for span in design.vary:
        text = f"{span.name}={span.low:g}..{span.high:g}"
        if span.name not in fields:  # the scenario's message lists its settings
            _named("--vary", text, scenario, design.scenario, {span.name: span.low})
        if "tuple" in fields[span.name]:
            raise ParameterError(f"--vary {text!r}: {span.name} is not a single number")
        if span.low > span.high:
            raise ParameterError(f"--vary {text!r}: LO {span.low:g} is above HI {span.high:g}")
        if span.name in seen:
            raise ParameterError(f"--vary {text!r}: {span.name} is varied twice")
        seen.add(span.name)
        if span.name in design.fixed:
            raise ParameterError(f"--vary {text!r}: {span.name} is also fixed by --set")
        for end in (span.low, span.high):
            _named("--vary", text, scenario, design.scenario, {**design.fixed, span.name: end})


def _named(option: str, value: str, check: Callable[..., Any], *args: object) -> Any:
    """``check(*args)``, its ParameterError prefixed with ``option`` and ``value``."""
    try:
        return check(*args)
    except ParameterError as err:
        raise ParameterError(f"{option} {value!r}: {err}") from None


def plan_study(design: StudyDesign) -> StudyPlan:
    """The study's plan, fixed by ``design.seed``; ParameterError (one line) for a bad design."""
    check_design(design)
    settings_seed, order_seed = np.random.SeedSequence(design.seed).spawn(2)
    draws = np.random.default_rng(settings_seed)
    orders = _orders(design.controllers, design.subjects, np.random.default_rng(order_seed))
    subjects: list[SubjectPlan] = []
    sessions: list[PlannedSession] = []
    volunteers: list[Scenario] = []
    for number, order in enumerate(orders, start=1):
        subject_id = validate_subject_id(f"S{number:03d}")
        drawn = {r.name: float(f"{draws.uniform(r.low, r.high):.6g}") for r in design.vary}
        where = f"subject {subject_id} ({', '.join(f'{k}={v:g}' for k, v in drawn.items())})"
        volunteers.append(_named("--vary", where, scenario, design.scenario, design.fixed | drawn))
        settings = settings_of(volunteers[-1])
        subjects.append(SubjectPlan(subject_id, drawn, settings, order))
        for repetition in range(1, design.repeats + 1):
            for controller in order:
                file = Path(subject_id, f"{subject_id}-{controller}-{repetition}.mcap")
                sessions.append(PlannedSession(subject_id, controller, repetition, settings, file))
    duration = design.duration_s or default_duration_s(volunteers)
    return StudyPlan(design, tuple(subjects), tuple(sessions), duration)


def _orders(controllers: Sequence[str], subjects: int, rng: np.random.Generator) -> list[Order]:
    """Each subject's order: the rows of a Latin square over the shuffled ``controllers``,
    handed out in a fresh random order to each block of ``len(controllers)`` subjects."""
    base = [controllers[i] for i in rng.permutation(len(controllers))]
    rows = [tuple(base[i:] + base[:i]) for i in range(len(base))]
    orders: list[Order] = []
    while len(orders) < subjects:
        orders += [rows[i] for i in rng.permutation(len(rows))]
    return orders[:subjects]


def collision_end_s(volunteer: Scenario) -> float:
    """When the volunteer's (first) collision is over, s after the scenario's start."""
    profiles = {"paper-end-effector": END_EFFECTOR_PROFILES, "paper-body": BODY_PROFILES}
    if volunteer.name in profiles:
        return max(p.segments[-1].stop_s for p in profiles[volunteer.name])
    return float(getattr(volunteer, "duration_s", 0.0))  # hand-contact: approach, hold, back


def default_duration_s(volunteers: Sequence[Scenario]) -> float:
    """Long enough for every volunteer's collision and RECOVERY_S after it, to 0.1 s above."""
    end_s = max((collision_end_s(v) for v in volunteers), default=0.0)
    return math.ceil(round((end_s + RECOVERY_S) * 10, 6)) / 10


def session_config(plan: StudyPlan, planned: PlannedSession, out: Path) -> SessionConfig:
    """The planned session's configuration, recording to ``out / planned.file``."""
    return SessionConfig(
        out=out / planned.file,
        subject_id=planned.subject_id,
        scenario=plan.design.scenario,
        scenario_settings=dict(planned.settings),
        duration_s=plan.duration_s,
        trajectory=TRAJECTORY,
        loop=LoopConfig(law=Law(planned.controller)),
        session_id=planned.file.stem,
        body_region=plan.design.body_region,
    )


def existing(plan: StudyPlan, index: int, out: Path) -> SessionStep | None:
    """None if session ``index``'s file is not there; else the step that skips it: ``done`` if
    it is the planned session recorded whole, ``skipped`` with a note saying why otherwise."""
    planned = plan.sessions[index]
    path = out / planned.file
    if not path.exists() and not path.is_symlink():
        return None

    def skip(why: str) -> SessionStep:
        note = f"{path}: {why}; not overwritten (move it away to record it again)"
        return SessionStep(index, planned, "skipped", note=note)

    try:
        info = inspect(path)
        session = info.session_info()
    except HilrigError as err:
        return skip(f"unreadable ({err})")
    if session is None:
        return skip("no session metadata")
    pairs = {
        "subject": (session.subject_id, planned.subject_id),
        "controller": (session.controller, planned.controller),
        "scenario": (session.scenario, plan.design.scenario),
    }
    differs = [f"{key} {got}, not {want}" for key, (got, want) in pairs.items() if got != want]
    if dict(session.scenario_settings) != json.loads(json.dumps(planned.settings)):
        differs.append("other scenario settings")
    if differs:
        return skip(f"not this plan's session ({'; '.join(differs)})")
    outcome = info.outcome
    if not info.complete or outcome is None or outcome.ended_early:
        return skip(f"incomplete ({(outcome and outcome.ended_by) or 'not closed cleanly'})")
    spans = [(t.end_ns or 0) - (t.start_ns or 0) for t in info.topics if t.topic == LOOP_TOPIC]
    span_s = max(spans, default=0) / 1e9
    if span_s < plan.duration_s - SPAN_TOLERANCE_S:
        return skip(f"interrupted ({span_s:.1f} s of {plan.duration_s:g} s)")
    return SessionStep(index, planned, "done")


def design_record(plan: StudyPlan) -> dict[str, Any]:
    """The plan as TOML's tables: the command, the design, each subject's draw and order."""
    design = plan.design
    return {
        "command": plan.design.command(),
        "software_version": __version__,
        "design": {
            "subjects": design.subjects,
            "controllers": list(design.controllers),
            "repeats": design.repeats,
            "scenario": design.scenario,
            "seed": design.seed,
            "vary": {r.name: [r.low, r.high] for r in design.vary},
            "set": dict(design.fixed),
            "duration_s": plan.duration_s,
            "body_region": design.body_region,
            "trajectory": TRAJECTORY,
            "rate_hz": LoopConfig().rate_hz,
        },
        "subjects": {
            s.subject_id: {
                "order": list(s.order),
                "drawn": s.drawn,
                "settings": {k: "none" if v is None else v for k, v in s.settings.items()},
            }
            for s in plan.subjects
        },
    }


def write_design(plan: StudyPlan, out: Path) -> Path:
    """Write the design to ``out/simulation.toml`` unless it is there; if another design is,
    to the first free ``simulation-N.toml`` (nothing is overwritten). The design's file."""
    import tomli_w

    record = design_record(plan)
    text = f"# hilrig study simulate: a synthetic study (DIR: this folder)\n{tomli_w.dumps(record)}"
    path, number = out / DESIGN_FILE, 1
    while path.exists():
        try:
            there = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            there = {}
        if {**there, "software_version": ""} == {**record, "software_version": ""}:
            return path
        number += 1
        path = out / f"{Path(DESIGN_FILE).stem}-{number}.toml"
    with new_files(path, create_folders=True) as (temporary,):
        temporary.write_text(text, encoding="utf-8")
    return path


def simulate_study(
    plan: StudyPlan,
    out: Path,
    *,
    on_session: Callable[[SessionStep], None] | None = None,
    on_begin: Callable[[int, PlannedSession], None] | None = None,
    stop: threading.Event | None = None,
    on_wait: Callable[[str], None] | None = None,
) -> StudyRun:
    """Record ``plan`` into ``out`` (every session checked, the design written, first); steps go
    to ``on_session``, sessions about to start to ``on_begin``, one waiting for the machine's
    other session to ``on_wait``. ``stop`` ends the session being recorded (its file is kept)
    and the study (StoppedWaitingError if it still waits). HilrigError when a session fails."""
    stop = stop or threading.Event()
    steps: list[SessionStep] = []
    todo: list[tuple[int, PlannedSession]] = []
    for index, planned in enumerate(plan.sessions):
        found = existing(plan, index, out)
        if found is None:
            session_config(plan, planned, out).check()
            todo.append((index, planned))
        else:
            steps.append(found)
    design_file = write_design(plan, out)
    report = on_session or (lambda step: None)
    for step in steps:
        report(step)
    for index, planned in todo:
        if stop.is_set():
            break
        if on_begin is not None:
            on_begin(index, planned)
        result = record_session(session_config(plan, planned, out), stop=stop, on_wait=on_wait)
        steps.append(SessionStep(index, planned, "recorded", result))
        report(steps[-1])
        problem = "; ".join(filter(None, (result.fault, result.recorder_error)))
        if problem:
            raise HilrigError(f"session {planned.file.stem} ended early: {problem}")
    return StudyRun(tuple(sorted(steps, key=lambda s: s.index)), design_file)
