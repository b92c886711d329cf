"""Closed-loop (counterfactual) replay against the truth the emulated rig can record: controller
A's recording predicts what controller B meets, and B recorded with the same volunteer says what
B met. A small version of the validation of docs/replay.md (``make bench`` runs the table)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from replay_helpers import EXAMPLE, HAND, HAND_SECONDS
from typer.testing import CliRunner

from hilrig.analysis import analyze, load_replay
from hilrig.cli import app
from hilrig.errors import ReplayError
from hilrig.replay import counterfactual, session_world
from hilrig.replay.counterfactual import figures
from hilrig.replay.job import closed_replay_file
from hilrig.replay.outputs import load_results
from hilrig.replay.results import INPUT_KEY, column_names
from hilrig.replay.session_world import load_world
from hilrig.replay.specs import parse_specs
from hilrig.rig import LoopConfig, SessionConfig, record_session
from hilrig.robot import RobotModel
from hilrig.world.contact import Mechanics

runner = CliRunner()
#: Recordings whose loop fell back to stale samples on more ticks than this share are recorded
#: again (at most ATTEMPTS times): the predictions compare two sessions of one volunteer, and a
#: machine loaded twice over (two test workers, or ``make test`` beside another) can stall a
#: session's rig for tens of milliseconds, the truth session's own stalls then being ones the
#: other's prediction cannot know of. A session's holds are replayed (its own reproduction is
#: not hurt by them: test_replayed_holds.py), so a few short stalls are accepted; about 5 s an
#: attempt when needed.
STALE_SHARE = 0.01
ATTEMPTS = 8


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same volunteer recorded under the adaptive and the fixed law."""
    folder = tmp_path_factory.mktemp("closed")
    paths = {}
    for law in ("adaptive", "fixed"):
        for attempt in range(ATTEMPTS):
            paths[law] = folder / f"{law}-{attempt}.mcap"
            config = SessionConfig(
                out=paths[law],
                subject_id="V001",
                scenario="hand-contact",
                scenario_settings=dict(HAND),
                duration_s=HAND_SECONDS,
                trajectory="hold",
                loop=LoopConfig(law=law),
            )
            summary = record_session(config, stop=threading.Event()).summary
            if summary.fallback_ticks <= STALE_SHARE * summary.ticks:
                break
        else:
            pytest.fail(
                f"{law}: no recording the loop kept up with in {ATTEMPTS} attempts (last: "
                f"{summary.fallback_ticks} fallback and {summary.hold_ticks} hold ticks of "
                f"{summary.ticks})"
            )
    return paths


def test_the_recorded_hand_is_identified(recordings: dict[str, Path]) -> None:
    world = load_world(recordings["fixed"], RobotModel())
    assert len(world.collisions) == 1
    fit = world.collisions[0].fit
    model = fit.model
    assert model.mechanics is Mechanics.SPRING_DAMPER
    np.testing.assert_allclose(model.direction_in_base, (1.0, 0.0, 0.0), atol=0.01)
    assert model.stiffness == pytest.approx(800.0, rel=0.1)
    assert model.motion is not None and model.motion.h_max_m == pytest.approx(0.02, abs=0.002)
    np.testing.assert_allclose(world.collisions[0].point_in_sensor_m, (0, 0, 0.1), atol=0.005)
    assert fit.r2 > 0.95 and fit.motion_gain > 3
    assert world.response.bandwidth_rad_s == 60.0  # the emulated plant's, known


@pytest.mark.parametrize(("a", "b"), [("adaptive", "fixed"), ("fixed", "adaptive")])
def test_a_reproduces_itself_and_predicts_b_better_than_open_loop(
    recordings: dict[str, Path], a: str, b: str
) -> None:
    replayed = closed_replay_file(recordings[a], parse_specs([b]))
    record = replayed.table.attrs[INPUT_KEY]["closed_loop"]
    (collision,) = record["collisions"]
    assert collision["reproduction_peak_error_pct"] <= 5.0
    assert record["stopped"] == [False, False]
    world_a = load_world(recordings[a], RobotModel())
    world_b = load_world(recordings[b], RobotModel())
    table = replayed.table
    predicted_xyz = table[[f"force_{axis}" for axis in "xyz"]].to_numpy()
    predicted = figures(world_a.t_s, predicted_xyz, world_a.reach(0))
    truth = figures(world_b.t_s, world_b.trace.force[:, :3], world_b.reach(0))
    open_loop = figures(world_a.t_s, world_a.trace.force[:, :3], world_a.reach(0))
    (row,) = record["predicted"][b]
    assert (row["peak_n"], row["impulse_n_s"]) == (predicted.peak_n, predicted.impulse_n_s)
    assert predicted.peak_n == pytest.approx(truth.peak_n, rel=0.2)
    assert predicted.impulse_n_s == pytest.approx(truth.impulse_n_s, rel=0.2)
    # the laws yield differently: the force A met is not the force B meets
    closed_error = abs(predicted.impulse_n_s - truth.impulse_n_s)
    assert closed_error < 0.5 * abs(open_loop.impulse_n_s - truth.impulse_n_s)


def test_the_cli_writes_the_contract_table_with_the_fitted_world(
    recordings: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "predicted.parquet"
    args = ["replay", str(recordings["adaptive"]), "--closed-loop", "-c", "fixed", "-o", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert any(line.startswith("closed loop: the arm's response: servo bandwidth 60.0 rad/s")
               for line in lines)  # fmt: skip
    assert any("collision 1 at" in line and "spring-damper along (1.00, " in line for line in lines)
    assert any(line.startswith("predicted for fixed: #1 peak ") for line in lines)
    verdict = "safety (hand recorded, contact area 1.96 cm^2): 1 within, 0 over; smallest margin"
    assert any(line.startswith(verdict) and "run fixed)" in line for line in lines)
    table, runs = load_results(out)
    assert list(table.columns) == column_names(runs["fixed"]["axes"])
    assert list(runs) == ["fixed"]


def test_a_scripted_force_is_replayed_as_recorded() -> None:
    result = runner.invoke(app, ["replay", str(EXAMPLE), "--closed-loop", "-c", "fixed"])
    assert result.exit_code == 0, result.output
    assert "a force source along (" in result.stdout
    replayed = closed_replay_file(EXAMPLE, parse_specs(["fixed"]))
    world = load_world(EXAMPLE, RobotModel())
    predicted = replayed.table[[f"force_{axis}" for axis in "xyz"]].to_numpy()
    np.testing.assert_array_equal(predicted, world.trace.force[:, :3])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--contact-model", "spring-damper"],
         "error: --contact-model spring-damper: only with --closed-loop"),
        (["--closed-loop", "--contact-model", "jelly"],
         "error: --contact-model 'jelly': unknown; known: auto, spring-damper, hunt-crossley, "
         "force-source"),
        (["--closed-loop", "--jobs", "2"],
         "error: --closed-loop simulates controllers offline on a recorded session: it takes no "
         "--verify, --rig, --resample or --jobs"),
    ],
)  # fmt: skip
def test_closed_loop_options_are_refused_in_one_line(args: list[str], message: str) -> None:
    result = runner.invoke(app, ["replay", str(EXAMPLE), *args])
    assert result.exit_code == 2
    assert result.stderr == message + "\n"


def test_a_table_cannot_be_replayed_closed_loop(tmp_path: Path) -> None:
    csv = tmp_path / "push.csv"
    csv.write_text("t,fx,fy,fz\n0,1,0,0\n0.001,1,0,0\n")
    result = runner.invoke(app, ["replay", str(csv), "--closed-loop"])
    assert result.exit_code == 2
    assert result.stderr == (
        f"error: {csv}: --closed-loop needs a recorded session (.mcap): the contact is fitted "
        "from the recorded force and the robot's measured motion\n"
    )


def test_runs_in_a_process_pool_give_the_same_table(
    recordings: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    specs = parse_specs(["adaptive", "variable-stiffness", "fixed"])
    monkeypatch.setattr(counterfactual, "POOL_MIN_TICKS", 10**12)
    alone = closed_replay_file(recordings["fixed"], specs).table
    monkeypatch.setattr(counterfactual, "POOL_MIN_TICKS", 0)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    assert counterfactual.choose_workers(4, 10) == 2
    pooled = closed_replay_file(recordings["fixed"], specs).table
    pd.testing.assert_frame_equal(pooled, alone)
    assert pooled.attrs == alone.attrs


def test_collisions_fitted_in_a_process_pool_are_fitted_alike(
    recordings: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    world = load_world(recordings["fixed"], RobotModel())
    (c,) = world.collisions
    window = slice(c.start, c.stop)
    hit = (world.t_s[window], world.trace.force[window, :3], world.contact_rec_m[window], None)
    quiet = (hit[0], np.zeros_like(hit[1]), hit[2], None)
    names = [f"collision {i}" for i in range(1, 5)]
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    alone = session_world._fits(names, [hit] * 4)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    assert session_world._fits(names, [hit] * 4) == alone == [c.fit] * 4
    with pytest.raises(ReplayError) as caught:
        session_world._fits(names, [hit, hit, quiet, hit])
    assert str(caught.value) == "collision 3: no contact force to fit a contact model to"


def test_each_predicted_controller_gets_its_own_safety_verdict(
    recordings: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "predicted.parquet"
    args = ["replay", str(recordings["adaptive"]), "--closed-loop", "-c", "fixed", "-o", str(out)]
    assert runner.invoke(app, args).exit_code == 0
    source = load_replay(out)
    assert source.body_region == "hand"  # the recording's, carried by hilrig.input
    (verdict,) = analyze(source).verdicts
    table, _ = load_results(out)
    force = np.linalg.norm(table[[f"force_{a}" for a in "xyz"]].to_numpy(), axis=1)
    assert verdict.run == "fixed" and verdict.body_region == "hand"
    assert verdict.peak_force_n == pytest.approx(force.max(), rel=1e-6)
    assert verdict.verdict == "within" and verdict.transient_limit_n == 280.0
