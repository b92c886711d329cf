"""``hilrig study simulate``: the plan (pure: seeded, counterbalanced, checked in one line per
mistake), resuming without overwriting, and one tiny study recorded on the emulated rig."""

from __future__ import annotations

import threading
import time
import tomllib
from collections import Counter
from dataclasses import replace
from pathlib import Path

import pytest

from hilrig.cli import run
from hilrig.errors import ParameterError
from hilrig.recording import inspect
from hilrig.study.catalogue import index, sessions
from hilrig.study.simulate import (
    EXAMPLE,
    PlannedSession,
    SettingRange,
    StudyDesign,
    existing,
    parse_controllers,
    parse_range,
    plan_study,
    simulate_study,
)

STIFFNESS = SettingRange("stiffness_n_m", 200.0, 1000.0)
SPEED = SettingRange("speed_m_s", 0.05, 0.2)
DESIGN = StudyDesign(subjects=6, controllers=("adaptive", "fixed"), vary=(STIFFNESS, SPEED))


def test_the_seed_fixes_the_plan() -> None:
    assert plan_study(DESIGN) == plan_study(DESIGN)
    other = plan_study(replace(DESIGN, seed=1))
    assert [s.drawn for s in other.subjects] != [s.drawn for s in plan_study(DESIGN).subjects]


def test_more_subjects_keep_the_first_subjects_draws_and_orders() -> None:
    few, many = plan_study(replace(DESIGN, subjects=4)), plan_study(replace(DESIGN, subjects=9))
    assert many.subjects[:4] == few.subjects


def test_each_subject_draws_its_settings_within_the_ranges_and_keeps_the_fixed_ones() -> None:
    plan = plan_study(replace(DESIGN, subjects=40, fixed={"damping_n_s_m": "20"}))
    assert [s.subject_id for s in plan.subjects][:3] == ["S001", "S002", "S003"]
    for subject in plan.subjects:
        assert 200.0 <= subject.drawn["stiffness_n_m"] <= 1000.0
        assert 0.05 <= subject.drawn["speed_m_s"] <= 0.2
        assert subject.settings["stiffness_n_m"] == subject.drawn["stiffness_n_m"]
        assert subject.settings["damping_n_s_m"] == 20.0
        assert subject.settings["hold_s"] == 1.0  # not varied, not set: the default
    assert len({s.drawn["stiffness_n_m"] for s in plan.subjects}) == 40


def test_orders_are_counterbalanced_and_repetitions_interleaved() -> None:
    controllers = ("adaptive", "fixed", "variable-stiffness")
    plan = plan_study(StudyDesign(subjects=6, controllers=controllers, repeats=2))
    for place in range(3):
        at_place = Counter(subject.order[place] for subject in plan.subjects)
        assert at_place == dict.fromkeys(controllers, 2)  # each at each place equally often
    for subject in plan.subjects:
        assert sorted(subject.order) == sorted(controllers)
        own = [s for s in plan.sessions if s.subject_id == subject.subject_id]
        assert [s.controller for s in own] == list(subject.order) * 2
        assert [s.repetition for s in own] == [1, 1, 1, 2, 2, 2]
    assert len({s.order for s in plan.subjects}) > 1


def test_files_are_named_by_subject_controller_and_repetition() -> None:
    plan = plan_study(replace(DESIGN, subjects=1, repeats=2))
    files = sorted(str(s.file) for s in plan.sessions)
    assert files == [
        "S001/S001-adaptive-1.mcap",
        "S001/S001-adaptive-2.mcap",
        "S001/S001-fixed-1.mcap",
        "S001/S001-fixed-2.mcap",
    ]
    wide = plan_study(StudyDesign(subjects=1000, controllers=("fixed",)))
    assert [s.subject_id for s in wide.subjects[998:]] == ["S999", "S1000"]  # S001 stays S001


def test_the_default_duration_holds_the_collision_and_its_recovery() -> None:
    hand = StudyDesign(subjects=2, controllers=("fixed",))
    assert plan_study(hand).duration_s == 6.6  # 2 s start, 0.8 s in, 1 s hold, 0.8 s out, +2 s
    slow = replace(hand, fixed={"speed_m_s": "0.05"})
    assert plan_study(slow).duration_s == 8.2
    assert plan_study(replace(hand, scenario="paper-end-effector")).duration_s == 8.0
    assert plan_study(replace(hand, scenario="paper-body")).duration_s == 7.5
    assert plan_study(replace(hand, duration_s=3.0)).duration_s == 3.0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"subjects": 0}, "--subjects 0: must be at least 1"),
        ({"repeats": 0}, "--repeats 0: must be at least 1"),
        ({"duration_s": 0.0}, "--duration-s 0: must be a finite number of seconds > 0"),
        ({"duration_s": -2.5}, "--duration-s -2.5: must be a finite number of seconds > 0"),
        ({"seed": -1}, "--seed -1: must be an integer >= 0"),
        (
            {"scenario": "shove"},
            "--scenario 'shove': unknown scenario 'shove'; known: hand-contact, none, paper-body,"
            " paper-end-effector",
        ),
        (
            {"controllers": ("adaptive", "pid")},
            "--controllers 'adaptive,pid': unknown controller 'pid'; known: fixed, "
            "variable-stiffness, adaptive",
        ),
        (
            {"vary": (SettingRange("stiffness_n_m", 1000.0, 200.0),)},
            "--vary 'stiffness_n_m=1000..200': LO 1000 is above HI 200",
        ),
        (
            {"vary": (SettingRange("stiffnes_n_m", 1.0, 2.0),)},
            "--vary 'stiffnes_n_m=1..2': scenario hand-contact: no setting 'stiffnes_n_m'; its "
            "settings: direction_in_base, start_s, gap_m, depth_m, speed_m_s, hold_s, "
            "stiffness_n_m, damping_n_s_m, contact_point_in_sensor, period_s",
        ),
        (
            {"vary": (SettingRange("direction_in_base", 0.0, 1.0),)},
            "--vary 'direction_in_base=0..1': direction_in_base is not a single number",
        ),
        (
            {"vary": (STIFFNESS, STIFFNESS)},
            "--vary 'stiffness_n_m=200..1000': stiffness_n_m is varied twice",
        ),
        (
            {"vary": (SettingRange("stiffness_n_m", -100.0, 200.0),)},
            "--vary 'stiffness_n_m=-100..200': scenario hand-contact: stiffness_n_m -100 must be"
            " >= 0",
        ),
        (
            {"vary": (STIFFNESS,), "fixed": {"stiffness_n_m": "500"}},
            "--vary 'stiffness_n_m=200..1000': stiffness_n_m is also fixed by --set",
        ),
        (
            {"fixed": {"hold_s": "long"}},
            "--set 'hold_s=long': scenario hand-contact: hold_s 'long' is not a number",
        ),
        (
            {"body_region": "elbow"},
            "--body-region 'elbow': unknown body region 'elbow'; known: skull, face, neck, back, "
            "chest, abdomen, pelvis, upper-arm, lower-arm, hand, thigh, lower-leg",
        ),
    ],
)
def test_every_mistake_is_one_line_naming_the_option(
    change: dict[str, object], message: str
) -> None:
    design = StudyDesign(subjects=2, controllers=("adaptive", "fixed"))
    with pytest.raises(ParameterError) as caught:
        plan_study(replace(design, **change))  # type: ignore[arg-type]
    assert str(caught.value) == message


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("stiffness_n_m", f"--vary 'stiffness_n_m': expected NAME=LO..HI, {EXAMPLE}"),
        ("stiffness_n_m=1-2", f"--vary 'stiffness_n_m=1-2': expected NAME=LO..HI, {EXAMPLE}"),
        ("=1..2", f"--vary '=1..2': expected NAME=LO..HI, {EXAMPLE}"),
        ("k=a..2", f"--vary 'k=a..2': LO..HI must be two numbers, {EXAMPLE}"),
    ],
)  # fmt: skip
def test_a_range_that_is_not_name_lo_hi_is_refused(text: str, message: str) -> None:
    with pytest.raises(ParameterError) as caught:
        parse_range(text)
    assert str(caught.value) == message


def test_controllers_are_named_once_each() -> None:
    assert parse_controllers("adaptive, fixed") == ("adaptive", "fixed")
    with pytest.raises(ParameterError) as caught:
        parse_controllers("fixed,adaptive,fixed")
    assert str(caught.value) == "--controllers 'fixed,adaptive,fixed': fixed named twice"


def test_a_drawn_subject_that_makes_no_volunteer_is_named() -> None:
    # each range is fine at the other's default, but a period must hold a slow hand's collision
    design = StudyDesign(
        subjects=3,
        controllers=("fixed",),
        vary=(SettingRange("period_s", 5.0, 5.2), SettingRange("speed_m_s", 0.05, 0.06)),
    )
    with pytest.raises(ParameterError) as caught:
        plan_study(design)
    assert str(caught.value).startswith("--vary 'subject S001 (period_s=5.")
    assert "scenario hand-contact: period_s 5." in str(caught.value)
    assert "is shorter than its collision" in str(caught.value)


def test_the_cli_refuses_a_bad_value_in_one_line_before_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    args = ["study", "simulate", str(out), "--subjects", "2", "--controllers", "adaptive,fixed"]
    assert run([*args, "--vary", "stiffness_n_m=1000..200"]) == 2
    assert capsys.readouterr().err == (
        "error: --vary 'stiffness_n_m=1000..200': LO 1000 is above HI 200\n"
    )
    assert run([*args, "--set", "hold_s"]) == 2
    assert capsys.readouterr().err == (
        "error: --set 'hold_s': expected KEY=VALUE, e.g. stiffness_n_m=800\n"
    )
    assert run([*args[:-1], "adaptive,pd"]) == 2
    assert "unknown controller 'pd'" in capsys.readouterr().err
    assert not out.exists()


def test_files_in_the_way_are_skipped_with_a_note_and_never_overwritten(tmp_path: Path) -> None:
    plan = plan_study(StudyDesign(subjects=1, controllers=("adaptive", "fixed")))
    assert existing(plan, 0, tmp_path) is None
    for session in plan.sessions:  # e.g. left by someone else: not a recording at all
        (tmp_path / session.file).parent.mkdir(exist_ok=True)
        (tmp_path / session.file).write_bytes(b"not a recording")
    done = simulate_study(plan, tmp_path)  # nothing to record: the rig is never started
    assert [s.status for s in done.steps] == ["skipped", "skipped"]
    for step in done.steps:
        path = tmp_path / step.session.file
        assert step.note.startswith(f"{path}: unreadable (")
        assert step.note.endswith("; not overwritten (move it away to record it again)")
        assert path.read_bytes() == b"not a recording"
    assert done.design_file == tmp_path / "simulation.toml"


def test_the_design_file_is_written_once_and_another_design_goes_beside_it(
    tmp_path: Path,
) -> None:
    design = StudyDesign(subjects=2, controllers=("adaptive", "fixed"), vary=(STIFFNESS,), seed=3)
    plan = plan_study(design)
    for session in plan.sessions:
        (tmp_path / session.file).parent.mkdir(exist_ok=True)
        (tmp_path / session.file).write_bytes(b"")
    assert simulate_study(plan, tmp_path).design_file == tmp_path / "simulation.toml"
    written = (tmp_path / "simulation.toml").read_text()
    record = tomllib.loads(written)
    assert record["command"] == (
        "hilrig study simulate DIR --subjects 2 --controllers adaptive,fixed --repeats 1 "
        "--scenario hand-contact --seed 3 --vary stiffness_n_m=200.0..1000.0"
    )
    assert record["design"]["seed"] == 3 and record["design"]["duration_s"] == 6.6
    s001 = record["subjects"]["S001"]
    assert s001["drawn"] == plan.subjects[0].drawn
    assert s001["order"] == list(plan.subjects[0].order)
    assert s001["settings"]["stiffness_n_m"] == plan.subjects[0].drawn["stiffness_n_m"]
    assert simulate_study(plan, tmp_path).design_file == tmp_path / "simulation.toml"
    assert (tmp_path / "simulation.toml").read_text() == written  # the same design: kept
    other = plan_study(replace(design, seed=4))
    assert simulate_study(other, tmp_path).design_file == tmp_path / "simulation-2.toml"
    assert (tmp_path / "simulation.toml").read_text() == written


def test_a_tiny_study_is_recorded_on_the_emulated_rig_and_resumed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    args = [
        "study",
        "simulate",
        str(out),
        "--subjects",
        "2",
        "--controllers",
        "adaptive,fixed",
        "--vary",
        "stiffness_n_m=200..1000",
        "--set",
        "start_s=0.5",
        "--duration-s",
        "3.5",
        "--seed",
        "7",
    ]
    assert run(args) == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "4 recorded, 0 recorded before, 0 skipped" in printed
    plan = plan_study(
        StudyDesign(
            subjects=2,
            controllers=("adaptive", "fixed"),
            vary=(STIFFNESS,),
            fixed={"start_s": "0.5"},
            duration_s=3.5,
            seed=7,
        )
    )
    files = sorted(p.relative_to(out) for p in out.rglob("*.mcap"))
    assert files == sorted(s.file for s in plan.sessions)
    stamps = {}
    for planned in plan.sessions:
        path = out / planned.file
        info = inspect(path)
        assert info.complete and info.outcome is not None and info.outcome.ticks > 0
        session = info.session_info()
        assert session is not None
        assert (session.subject_id, session.controller) == (
            planned.subject_id,
            planned.controller,
        )
        assert session.scenario == "hand-contact"
        assert session.scenario_settings["stiffness_n_m"] == planned.settings["stiffness_n_m"]
        assert session.scenario_settings["start_s"] == 0.5
        assert 200.0 <= session.scenario_settings["stiffness_n_m"] <= 1000.0  # type: ignore[operator]
        assert f"{planned.file.stem}: " in printed
        stamps[path] = path.stat().st_mtime_ns
    assert (out / "simulation.toml").is_file()
    # every volunteer met the tool: the loop logged a collision in each session
    catalogue = sessions(index(out)[0])
    assert len(catalogue) == 4 and (catalogue["collisions"] >= 1).all()
    assert run(args) == 0  # the same command again: nothing new
    assert "0 recorded, 4 recorded before, 0 skipped" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    shown = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert shown == ["S001", "S002", "simulation.toml"]
    # a second repetition, stopped as its first session's file is open: kept, not taken as done
    # (stopped before it, a session waiting for another worker's session would give up instead)
    more = plan_study(replace(plan.design, repeats=2))
    stop = threading.Event()

    def stop_once_open(index: int, session: PlannedSession) -> None:
        def watch() -> None:
            while not (out / session.file).exists():
                time.sleep(0.005)
            stop.set()

        threading.Thread(target=watch, daemon=True).start()

    done = simulate_study(more, out, on_begin=stop_once_open, stop=stop)
    assert [s.status for s in done.steps] == ["done", "done", "recorded", "done", "done"]
    assert done.design_file == out / "simulation-2.toml"
    cut = done.steps[2]
    assert cut.session.repetition == 2 and (out / cut.session.file).is_file()
    again = existing(more, cut.index, out)
    assert again is not None and again.status == "skipped"
    assert again.note.startswith(f"{out / cut.session.file}: incomplete (stopped by its caller)")
