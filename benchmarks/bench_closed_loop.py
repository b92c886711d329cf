"""Closed-loop (counterfactual) replay against ground truth on the emulated rig, and its speed.

Six emulated volunteers (``hand-contact``) spread over the scenario's range like a small Latin
hypercube: stiffness 200-1000 N/m, approach speed 0.05-0.2 m/s, depth 0.01-0.04 m, each base
axis as the push's direction twice. Each is recorded once under each of the three controllers
(adaptive, variable-stiffness, fixed; the live loop's presets, ``hold`` trajectory), into a
temporary folder. Then, for every recording A and every other controller B,
``closed_replay_file(A, [B])`` predicts B closed loop (one call per A runs both other controllers:
each run is simulated on its own, so this is the same as one call per pair), and per collision
(matched by index; a pair whose recordings differ in their number of collisions is skipped and
counted) it is compared with B's own recording:

- reproduction: the recorded controller re-simulated against A's recorded force (the record's
  ``reproduction_peak_error_pct``), target worst <= 5 %;
- closed-loop prediction error of B's peak |F| and impulse of |F| (|pred - truth| / truth),
  target median <= 10 %, worst <= 20 %;
- open-loop error beside it: A's recorded force taken as B's (what open-loop replay assumes);

Timed: ``counterfactual.closed_loop`` with the three controllers on a 10-minute session (a
30 s recording of the default hand, a collision every 5 s, played again and again with its
collisions: 1 kHz ticks), median of several calls after a warm-up; the call also re-simulates
the recorded controller once, and that is counted in its time. Reported as seconds and x real
time (the session's duration over the wall time), target >= 100; and the time to read and fit
the 30 s recording's world (its 6 collisions).
"""

from __future__ import annotations

import math
import statistics
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table

from benchmarks.harness import Result
from hilrig.control import Law
from hilrig.errors import ReplayError
from hilrig.replay import Run, parse_specs
from hilrig.replay.counterfactual import closed_loop, figures
from hilrig.replay.inputs import session_index
from hilrig.replay.job import closed_replay_file
from hilrig.replay.session_world import SessionWorld, load_world
from hilrig.replay.verify import recorded_controller
from hilrig.rig import LoopConfig, SessionConfig, record_session
from hilrig.robot import RobotModel

SUITE = "closed_loop"
LAWS = ("adaptive", "variable-stiffness", "fixed")
GAP_M = 0.05  # the scenario's default: where the hand starts, short of the tool
START_S, HOLD_S, TAIL_S = 2.0, 1.0, 0.5
TIMING_REPEATS = 3
TIMED_S = 600.0  # the timed session: 10 minutes
TIMED_RECORDED_S, TIMED_PERIOD_S = 30.0, 5.0  # recorded, then repeated to TIMED_S
#: (stiffness N/m, speed m/s, depth m, direction): each range in six steps, each axis twice.
CASES: tuple[tuple[float, float, float, tuple[float, float, float]], ...] = (
    (200.0, 0.14, 0.040, (1.0, 0.0, 0.0)),
    (360.0, 0.05, 0.016, (0.0, 1.0, 0.0)),
    (520.0, 0.20, 0.028, (0.0, 0.0, 1.0)),
    (680.0, 0.08, 0.034, (1.0, 0.0, 0.0)),
    (840.0, 0.11, 0.010, (0.0, 1.0, 0.0)),
    (1000.0, 0.17, 0.022, (0.0, 0.0, 1.0)),
)
KEYS = ("closed_peak", "closed_impulse", "open_peak", "open_impulse")
SHORT = {"adaptive": "adaptive", "variable-stiffness": "var-stiff", "fixed": "fixed"}
Floats = NDArray[np.float64]


def run() -> list[Result]:
    console = Console()
    model = RobotModel()
    cases: list[dict[str, Any]] = []
    reproduction: list[float] = []
    reproduction_impulse: list[float] = []
    errors: dict[tuple[str, str], dict[str, list[float]]] = {
        (a, b): {k: [] for k in KEYS} for a in LAWS for b in LAWS if a != b
    }
    skipped: list[str] = []
    refused: list[str] = []
    with tempfile.TemporaryDirectory(prefix="hilrig-bench-closed-") as tmp:
        for number, (stiffness, speed, depth, direction) in enumerate(CASES, 1):
            settings: dict[str, object] = {
                "stiffness_n_m": stiffness,
                "speed_m_s": speed,
                "depth_m": depth,
                "direction_in_base": list(direction),
                "period_s": None,
            }
            duration = START_S + 2 * (GAP_M + depth) / speed + HOLD_S + TAIL_S
            label = f"case {number} (k {stiffness:g} N/m, v {speed:g} m/s, d {depth:g} m, "
            label += f"dir {'xyz'[direction.index(1.0)]})"
            paths, recordings = _record(Path(tmp), number, settings, duration)
            worlds = {law: load_world(paths[law], model) for law in LAWS}
            for law in LAWS:
                recordings[law]["collisions"] = len(worlds[law].collisions)
            pairs: list[dict[str, Any]] = []
            for a in LAWS:
                others = [b for b in LAWS if b != a]
                try:
                    replayed = closed_replay_file(paths[a], parse_specs(others))
                except ReplayError as err:
                    refused.append(f"case {number}: {a} -> {', '.join(others)}: {err}")
                    pairs += [{"from": a, "to": b, "status": f"refused: {err}"} for b in others]
                    continue
                record = replayed.table.attrs["hilrig.input"]["closed_loop"]
                for c in record["collisions"]:
                    reproduction.append(float(c["reproduction_peak_error_pct"]))
                    reproduction_impulse.append(float(c["reproduction_impulse_error_pct"]))
                table = replayed.table
                for b in others:
                    rows = table[table["run"] == b]
                    pred = rows[["force_x", "force_y", "force_z"]].to_numpy(np.float64)
                    pair = _compare(worlds[a], worlds[b], pred, errors[(a, b)])
                    pair |= {"from": a, "to": b, "reproduction": _reproduction(record)}
                    pair |= {"hold_ticks": record["hold_ticks"], "stopped": record["stopped"]}
                    if pair["status"] != "compared":
                        skipped.append(f"case {number}: {a} -> {b}: {pair['status']}")
                    pairs.append(pair)
            cases.append(
                {"case": label, "settings": settings, "duration_s": duration}
                | {"recordings": recordings, "pairs": pairs}
            )
            console.print(f"  {label}: recorded and replayed")
        timing = _timing(_record_timed(Path(tmp)), model)
    _print(console, errors, skipped, refused)
    return _results(cases, errors, reproduction, reproduction_impulse, skipped, refused, timing)


def _record(
    folder: Path, number: int, settings: dict[str, object], duration: float
) -> tuple[dict[str, Path], dict[str, dict[str, Any]]]:
    """Each controller's recording of one case, and what its loop reported."""
    paths: dict[str, Path] = {}
    recordings: dict[str, dict[str, Any]] = {}
    for law in LAWS:
        out = folder / f"case{number}-{law}.mcap"
        result = record_session(
            SessionConfig(
                out=out,
                subject_id="V001",
                scenario="hand-contact",
                scenario_settings=settings,
                duration_s=duration,
                trajectory="hold",
                loop=LoopConfig(law=Law(law)),
            ),
            stop=threading.Event(),
        )
        summary = result.summary
        paths[law] = out
        recordings[law] = {
            "ticks": summary.ticks,
            "missed_deadlines": summary.missed_deadlines,
            "hold_ticks": summary.hold_ticks,
            "drops": result.drops,
            "ended_by": result.ended_by,
        }
    return paths, recordings


def _pct(value: float, truth: float) -> float:
    return 100.0 * abs(value - truth) / truth if truth > 0 else float("nan")


def _compare(
    a: SessionWorld, b: SessionWorld, pred: Floats, into: dict[str, list[float]]
) -> dict[str, Any]:
    """Per collision: B predicted closed loop from A (``pred``, A's ticks) and open loop (A's
    recorded force), against B's recording. The errors are also appended to ``into``."""
    if len(pred) != len(a.t_s):
        return {"status": f"prediction has {len(pred)} rows for {len(a.t_s)} ticks"}
    pair: dict[str, Any] = {"status": "compared"}
    if len(a.collisions) != len(b.collisions):
        return pair | {"status": f"collisions differ: {len(a.collisions)} vs {len(b.collisions)}"}
    rows = [_row(a, b, pred, i) for i in range(len(a.collisions))]
    for row in rows:
        for key in KEYS:
            into[key].append(row[key])
    return pair | {"collisions": rows}


def _row(a: SessionWorld, b: SessionWorld, pred: Floats, i: int) -> dict[str, float]:
    truth = figures(b.t_s, b.trace.force[:, :3], b.reach(i))
    closed = figures(a.t_s, pred, a.reach(i))
    opened = figures(a.t_s, a.trace.force[:, :3], a.reach(i))
    ca = a.collisions[i]
    return {
        "t_start_s": float(a.t_s[ca.start]),
        "t_end_s": float(a.t_s[ca.stop - 1]),
        "truth_peak_n": truth.peak_n,
        "truth_impulse_n_s": truth.impulse_n_s,
        "closed_peak_n": closed.peak_n,
        "closed_impulse_n_s": closed.impulse_n_s,
        "open_peak_n": opened.peak_n,
        "open_impulse_n_s": opened.impulse_n_s,
        "closed_peak": _pct(closed.peak_n, truth.peak_n),
        "closed_impulse": _pct(closed.impulse_n_s, truth.impulse_n_s),
        "open_peak": _pct(opened.peak_n, truth.peak_n),
        "open_impulse": _pct(opened.impulse_n_s, truth.impulse_n_s),
    }


def _reproduction(record: dict[str, Any]) -> list[dict[str, Any]]:
    keys = (
        "recorded_peak_n",
        "reproduced_peak_n",
        "reproduction_peak_error_pct",
        "reproduction_impulse_error_pct",
        "r2",
        "mechanics",
        "t_s",
    )
    return [{k: c[k] for k in keys} for c in record["collisions"]]


def _record_timed(folder: Path) -> Path:
    """A ``TIMED_RECORDED_S`` session of the default hand (a collision every 5 s), adaptive."""
    out = folder / "timed.mcap"
    settings: dict[str, object] = {"period_s": TIMED_PERIOD_S}
    config = SessionConfig(out=out, subject_id="V002", scenario="hand-contact",
                           scenario_settings=settings, duration_s=TIMED_RECORDED_S,
                           trajectory="hold")  # fmt: skip
    record_session(config, stop=threading.Event())
    return out


def _timing(path: Path, model: RobotModel) -> dict[str, Any]:
    """``closed_loop`` with the three controllers on a ``TIMED_S`` session: ``path``'s world
    repeated end to end (its collisions with it); the call re-simulates the recorded controller
    too. The median wall time of several calls after a warm-up, and the fitting's time."""
    start = time.perf_counter()
    world = load_world(path, model)
    fit_s = time.perf_counter() - start
    long = _repeated(world, TIMED_S)
    axes = world.trace.axis_names
    law, params, _ = recorded_controller(path, session_index(path), axes)
    runs = [Run.from_spec(spec, axes) for spec in parse_specs(list(LAWS))]
    recorded = Run("recorded", law, params)
    closed_loop(long, runs, recorded)  # warm-up: compiled code loaded, buffers touched
    walls = []
    for _ in range(TIMING_REPEATS):
        start = time.perf_counter()
        closed_loop(long, runs, recorded)
        walls.append(time.perf_counter() - start)
    return {
        "session": f"{path.name} repeated to {TIMED_S:g} s",
        "ticks": len(long.t_s),
        "collisions": len(long.collisions),
        "duration_s": float(long.t_s[-1] + long.trace.dt_s),
        "controllers": list(LAWS),
        "simulated_per_call": len(runs) + 1,
        "walls_s": walls,
        "wall_s": statistics.median(walls),
        "fit_s": fit_s,
        "fitted_collisions": len(world.collisions),
        "fitted_session_s": float(world.t_s[-1] + world.trace.dt_s),
    }


def _repeated(world: SessionWorld, seconds: float) -> SessionWorld:
    """``world`` played again and again for ``seconds``: times, rows and collisions shifted."""
    span = float(world.t_s[-1]) + world.trace.dt_s
    times = math.ceil(seconds / span)
    n = len(world.t_s)
    shifts = np.repeat(np.arange(times) * span, n)
    trace = replace(
        world.trace,
        t_s=np.tile(world.t_s, times) + shifts,
        force=np.tile(world.trace.force, (times, 1)),
    )
    collisions = []
    for k in range(times):
        for c in world.collisions:
            model = c.fit.model
            motion = model.motion
            if motion is not None:
                shift = k * span
                motion = replace(
                    motion, t_full_s=motion.t_full_s + shift, t_back_s=motion.t_back_s + shift
                )
            fit = replace(c.fit, model=replace(model, motion=motion))
            collisions.append(replace(c, start=c.start + k * n, stop=c.stop + k * n, fit=fit))
    return replace(
        world,
        trace=trace,
        position_d=np.tile(world.position_d, (times, 1)),
        rotation_d=np.tile(world.rotation_d, (times, 1, 1)),
        orientation_d=np.tile(world.orientation_d, (times, 1)),
        contact_rec_m=np.tile(world.contact_rec_m, (times, 1)),
        collisions=tuple(collisions),
    )


def _stats(values: Sequence[float]) -> tuple[float, float]:
    """Median and worst (largest); NaN for none."""
    if not values:
        return float("nan"), float("nan")
    array = np.asarray(values, dtype=np.float64)
    return float(np.median(array)), float(array.max())


def _print(
    console: Console,
    errors: dict[tuple[str, str], dict[str, list[float]]],
    skipped: list[str],
    refused: list[str],
) -> None:
    for prefix, title in (("", "per collision"),):
        table = Table(title=f"predicted vs recorded, {title}: error % median/worst")
        table.add_column("recorded -> predicted")
        table.add_column("n", justify="right")
        for what in ("closed peak", "closed imp.", "open peak", "open imp."):
            table.add_column(what, justify="right")
        for (a, b), values in errors.items():
            cells = []
            for key in KEYS:
                median, worst = _stats(values[prefix + key])
                cells.append(f"{median:.1f}/{worst:.1f}")
            n = str(len(values[prefix + KEYS[0]]))
            table.add_row(f"{SHORT[a]} -> {SHORT[b]}", n, *cells)
        console.print(table)
    for line in [*refused, *skipped]:
        console.print(f"  [yellow]{line}[/]")


def _results(
    cases: list[dict[str, Any]],
    errors: dict[tuple[str, str], dict[str, list[float]]],
    reproduction: list[float],
    reproduction_impulse: list[float],
    skipped: list[str],
    refused: list[str],
    timing: dict[str, Any],
) -> list[Result]:
    pooled = {key: [v for values in errors.values() for v in values[key]] for key in KEYS}
    counts = {
        "pairs": 6 * len(cases),
        "collisions_compared": len(pooled["closed_peak"]),
        "pairs_skipped": skipped,
        "pairs_refused": refused,
    }
    detail = {"cases": cases, **counts}

    def row(
        name: str, value: float, target: float | None = None, full: dict[str, Any] | None = None
    ) -> Result:
        if target is None:
            return Result(SUITE, name, value, "%", "", None, full or counts)
        return Result(SUITE, name, value, "%", f"<= {target:g}", value <= target, full or counts)

    results = []
    rep_median, rep_worst = _stats(reproduction)
    results.append(row("reproduction of the recorded force, peak error median", rep_median))
    results.append(row("reproduction, peak error worst", rep_worst, 5.0))
    results.append(row("reproduction, impulse error worst", _stats(reproduction_impulse)[1]))
    for what, label in (("peak", "peak |F|"), ("impulse", "impulse of |F|")):
        closed_median, closed_worst = _stats(pooled[f"closed_{what}"])
        open_median, open_worst = _stats(pooled[f"open_{what}"])
        full = detail if what == "peak" else None
        results += [
            row(f"closed-loop prediction, {label} error median", closed_median, 10.0, full),
            row("... worst", closed_worst, 20.0),
            row(f"open loop (recorded force as is), {label} error median", open_median),
            row("... worst", open_worst),
        ]
    results.append(
        Result(SUITE, "pairs skipped (collision counts differ)", len(skipped), "pairs", "", None,
               counts)
    )  # fmt: skip
    results.append(
        Result(SUITE, "pairs refused (fit too poor)", len(refused), "pairs", "== 0",
               not refused, counts)
    )  # fmt: skip
    wall = float(timing["wall_s"])
    note = {
        **timing,
        "note": "each closed_loop call also re-simulates the recorded controller (4 runs in "
        "all); that time is included",
    }
    realtime = float(timing["duration_s"]) / wall
    results += [
        Result(SUITE, "closed-loop re-simulation, 10-min session, 3 controllers", wall, "s",
               "", None, note),
        Result(SUITE, "... as x real time", realtime, "x", ">= 100", realtime >= 100, note),
        Result(SUITE, f"fitting a {TIMED_RECORDED_S:g} s session's world "
               f"({timing['fitted_collisions']} collisions)", float(timing["fit_s"]), "s", "",
               None, note),
    ]  # fmt: skip
    return results
