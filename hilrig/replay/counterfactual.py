"""Counterfactual replay: what force the person would have felt under other controllers.

    world = load_world(path, RobotModel())          # contacts and the arm's response, fitted
    result = closed_loop(world, runs, recorded)     # the result table, closed loop

Before predicting, every collision's fit is checked (:meth:`ContactFit.check`: a poor fit is
refused in one line naming the collision and the figure), and the recorded controller is
re-simulated: its predicted peak force and impulse per collision, against the recorded ones,
are the reproduction error that comes with every prediction (``hilrig.input`` of the table).
"""

from __future__ import annotations

import multiprocessing as mp
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.control import ParameterError, damping_ratio_rows, make
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.errors import ReplayError
from hilrig.recording.schema import AXES
from hilrig.replay.blocks import Blocks
from hilrig.replay.closed_loop import (
    COLLISION_COLUMNS,
    DAMPING,
    H_MAX,
    MECH,
    MECHANICS_CODE,
    POINT,
    REFERENCE,
    START,
    STIFFNESS,
    STOP,
    T_BACK,
    T_FULL,
    V_IN,
    V_OUT,
    U,
    kernel_inputs,
    simulate_kernel,
)
from hilrig.replay.engine import local_cores
from hilrig.replay.recorded_holds import ALL_OK
from hilrig.replay.results import FLOAT_ROWS, INPUT_KEY, Run, frame
from hilrig.replay.session_world import SessionWorld
from hilrig.robot import RobotModel
from hilrig.tick.kernel import HOLD_TICKS, STOPPED, CompiledTick
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.world.contact import ONSET_SHARE
from hilrig.world.plant import servo_limits

#: ``progress(done, total)`` in runs (the recorded controller's first).
RunProgress = Callable[[int, int], None]
#: Runs holding this many ticks together go to a process pool (measured: a 10-minute session's
#: four runs took 1.6x less time on 2 cores; docs/replay.md).
POOL_MIN_TICKS = 200_000


@dataclass(frozen=True)
class CollisionFigures:
    """A run's peak force (N, |F| over x, y, z) and impulse (N*s, of |F|) in a collision."""

    peak_n: float
    impulse_n_s: float


@dataclass(frozen=True)
class Simulated:
    """What a closed-loop run did besides its table rows: hold ticks, a protective stop."""

    hold_ticks: int
    stopped: bool


def packed_collisions(world: SessionWorld) -> NDArray[np.float64]:
    """The collisions as the kernel reads them: each applies from its first tick to the next's."""
    rows = np.zeros((len(world.collisions), COLLISION_COLUMNS))
    for i, collision in enumerate(world.collisions):
        model = collision.fit.model
        row = rows[i]
        row[START] = collision.start
        row[STOP] = (
            world.collisions[i + 1].start if i + 1 < len(world.collisions) else len(world.t_s)
        )
        row[MECH] = MECHANICS_CODE[model.mechanics]
        row[U : U + 3] = model.direction_in_base
        row[STIFFNESS], row[DAMPING] = model.stiffness, model.damping
        if model.motion is not None:
            m = model.motion
            row[T_FULL], row[T_BACK], row[H_MAX] = m.t_full_s, m.t_back_s, m.h_max_m
            row[V_IN], row[V_OUT] = m.v_in_m_s, m.v_out_m_s
        row[REFERENCE : REFERENCE + 3] = collision.reference_m
        row[POINT : POINT + 3] = collision.point_in_sensor_m
    return rows


def simulate_run(
    world: SessionWorld,
    run: Run,
    model: RobotModel,
    blocks: Blocks,
    row0: int,
    ticks: int | None = None,
) -> Simulated:
    """``run`` closed loop over ``world`` (its first ``ticks``; None: all) into ``blocks`` rows
    ``row0`` .. ``row0 + ticks``."""
    dt_s = world.trace.dt_s
    try:
        controller = make(run.law, run.params, AXES, dt_s)
    except ParameterError as err:
        raise ReplayError(f"run {run.name}: {err}") from err
    q0 = world.q_start_rad
    clamp = SafetyClamp(SafetyConfig(dt_s=dt_s), model, q0)
    tick = CompiledTick.build(controller, model, clamp, GravityCompensator(), q0, dt_s)
    tick.compensation[:] = 0.0  # the recorded input is compensated already
    n = len(world.t_s) if ticks is None else ticks
    servo = np.zeros((4, 6))
    servo[0] = q0
    servo[3] = q0
    response = world.response
    simulate_kernel(
        world.t_s[:n],
        world.trace.force,
        world.position_d,
        world.rotation_d,
        world.contact_rec_m,
        world.link_flags,
        packed_collisions(world),
        tick.kernel_args(),
        kernel_inputs(tick),
        servo,
        servo_limits(model.limits),
        np.zeros(n),
        np.zeros((n, 6)),
        np.array([response.bandwidth_rad_s, response.substep_s, response.delay_s]),
        blocks.floats,
        blocks.contact,
        row0,
        FLOAT_ROWS["force"],
    )
    rows = slice(row0, row0 + n)
    zeta = blocks.floats[:, FLOAT_ROWS["zeta"], rows]
    damping_ratio_rows(
        blocks.floats[:, FLOAT_ROWS["damping"], rows],
        blocks.floats[:, FLOAT_ROWS["stiffness"], rows],
        controller.mass,
        zeta,
    )
    if not np.isfinite(blocks.floats[:, :, rows]).all():
        raise ReplayError(f"run {run.name}: the closed loop's result is not finite")
    return Simulated(int(tick.counters[HOLD_TICKS]), bool(tick.counters[STOPPED]))


def figures(
    t_s: NDArray[np.float64], force_xyz: NDArray[np.float64], ticks: slice
) -> CollisionFigures:
    """Peak and impulse of ``|F|`` (n, 3) over ``ticks`` (e.g. ``SessionWorld.reach(i)``)."""
    magnitude = np.linalg.norm(force_xyz[ticks], axis=1)
    return CollisionFigures(
        float(magnitude.max(initial=0.0)), float(np.trapezoid(magnitude, t_s[ticks]))
    )


def predicted(world: SessionWorld, force_xyz: NDArray[np.float64]) -> list[dict[str, float]]:
    """Per collision, a run's predicted peak force and impulse over its reach, and how long its
    contact lasts past the recorded contact's end (there the body's motion is extrapolated)."""
    rows = []
    for i, c in enumerate(world.collisions):
        ticks = world.reach(i)
        got = figures(world.t_s, force_xyz, ticks)
        magnitude = np.linalg.norm(force_xyz[ticks], axis=1)
        touching = np.flatnonzero(magnitude > ONSET_SHARE * c.fit.peak_n)
        last = float(world.t_s[ticks][touching[-1]]) if len(touching) else c.fit.t_off_s
        rows.append(
            {
                "peak_n": got.peak_n,
                "impulse_n_s": got.impulse_n_s,
                "contact_beyond_s": max(0.0, last - c.fit.t_off_s),
            }
        )
    return rows


def closed_loop(
    world: SessionWorld,
    runs: Sequence[Run],
    recorded: Run,
    *,
    progress: RunProgress | None = None,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The result table of ``runs`` closed loop, and the closed-loop record (models, fits,
    reproduction error, per-run hold ticks) that goes into its ``hilrig.input``. Raises
    ReplayError (one line) for a collision whose fit is too poor to predict from."""
    for collision in world.collisions:
        try:
            collision.fit.check(collision.name)
        except ParameterError as err:
            raise ReplayError(str(err)) from err
    model = RobotModel()
    n = len(world.t_s)
    everything = [recorded, *runs]
    workers = choose_workers(len(everything), n)
    blocks = Blocks.allocate(AXES, len(FLOAT_ROWS), n * len(everything), shared=workers > 1)
    blocks.settle()
    if workers > 1:
        done = _in_pool(world, everything, model, blocks, workers, progress)
    else:
        done = []
        for index, run in enumerate(everything):
            done.append(simulate_run(world, run, model, blocks, index * n))
            if progress is not None:
                progress(index + 1, len(everything))
    force_row = FLOAT_ROWS["force"]
    reproduced = blocks.floats[:3, force_row, :n].T
    record = closed_loop_record(world, reproduced, done)
    record["predicted"] = {
        run.name: predicted(world, blocks.floats[:3, force_row, (i + 1) * n : (i + 2) * n].T)
        for i, run in enumerate(runs)
    }
    table = frame(world.trace, list(runs), _tail(blocks, n))
    table.attrs[INPUT_KEY] = {**table.attrs[INPUT_KEY], "closed_loop": record}
    return table, record


def choose_workers(runs: int, ticks: int) -> int:
    """Processes for ``runs`` closed-loop runs of ``ticks`` each: the local cores (at most one
    per run) once the runs together hold ``POOL_MIN_TICKS``, else 1 (forking costs more)."""
    if runs > 1 and runs * ticks >= POOL_MIN_TICKS and "fork" in mp.get_all_start_methods():
        return min(runs, local_cores())
    return 1


_inherited: list[tuple[SessionWorld, Sequence[Run], RobotModel, Blocks]] = []


def _work(index: int) -> Simulated:
    world, runs, model, blocks = _inherited[-1]
    return simulate_run(world, runs[index], model, blocks, index * len(world.t_s))


def _in_pool(
    world: SessionWorld,
    runs: Sequence[Run],
    model: RobotModel,
    blocks: Blocks,
    workers: int,
    progress: RunProgress | None,
) -> list[Simulated]:
    """Every run in forked processes writing into the shared ``blocks``; compiled once first
    (a tick of the first run), so that the workers inherit the machine code."""
    simulate_run(world, runs[0], model, blocks, 0, ticks=1)
    _inherited.append((world, runs, model, blocks))
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("fork")) as pool:
            futures = {pool.submit(_work, i): i for i in range(len(runs))}
            for done, future in enumerate(as_completed(futures), 1):
                future.result()  # a run's ReplayError, raised here
                if progress is not None:
                    progress(done, len(runs))
            return [future.result() for future in futures]
    finally:
        _inherited.pop()


def _tail(blocks: Blocks, n: int) -> Blocks:
    """The blocks without the recorded controller's first ``n`` rows (no copy)."""
    return Blocks(blocks.floats[:, :, n:], blocks.contact[:, n:])


def closed_loop_record(
    world: SessionWorld, reproduced_xyz: NDArray[np.float64], done: Sequence[Simulated]
) -> dict[str, Any]:
    """JSON-ready: the arm's response, each collision's model, fit and reproduction error (and,
    added by :func:`closed_loop`, ``predicted``: per run and collision :func:`predicted`)."""
    r = world.response
    collisions = []
    for i, c in enumerate(world.collisions):
        fit, model = c.fit, c.fit.model
        recorded = figures(world.t_s, world.trace.force[:, :3], world.reach(i))
        again = figures(world.t_s, reproduced_xyz, world.reach(i))
        motion = model.motion
        collisions.append(
            {
                "name": c.name,
                "t_s": [float(world.t_s[c.start]), float(world.t_s[c.stop - 1])],
                "mechanics": model.mechanics.value,
                "direction_in_base": list(model.direction_in_base),
                "contact_point_in_sensor_m": list(c.point_in_sensor_m),
                "stiffness": model.stiffness,
                "damping": model.damping,
                "surface": None if motion is None else vars(motion),
                "r2": fit.r2,
                "rms_n": fit.rms_n,
                "motion_gain": fit.motion_gain,
                "recorded_peak_n": recorded.peak_n,
                "recorded_impulse_n_s": recorded.impulse_n_s,
                "reproduced_peak_n": again.peak_n,
                "reproduced_impulse_n_s": again.impulse_n_s,
                "reproduction_peak_error_pct": _error_pct(again.peak_n, recorded.peak_n),
                "reproduction_impulse_error_pct": _error_pct(
                    again.impulse_n_s, recorded.impulse_n_s
                ),
            }
        )
    return {
        "response": {
            "bandwidth_rad_s": r.bandwidth_rad_s,
            "delay_s": r.delay_s,
            "substep_s": r.substep_s,
            "rms_rad": r.rms_rad,
            "source": r.source,
            "recorded_sensor_to_command_us": (
                None if world.sensor_to_command_us is None else list(world.sensor_to_command_us)
            ),
        },
        "collisions": collisions,
        "recorded_link_holds": int(np.count_nonzero(world.link_flags != ALL_OK)),
        "hold_ticks": [s.hold_ticks for s in done],
        "stopped": [s.stopped for s in done],
    }


def _error_pct(value: float, truth: float) -> float:
    return 100.0 * abs(value - truth) / truth if truth > 0 else float("nan")
