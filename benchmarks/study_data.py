"""The study suite's data: 50 subjects x 2 controllers, one 10-minute 1 kHz session each.

Each subject pushes the replay suite's input (the paper's collision profiles every 30 s, with
sensor noise, seeded per subject) scaled by its own factor (0.6 .. 1.6); each session holds
what a study reads of a recorded loop: ``/controller/state`` (the controller's response to that
input, computed by hilrig's replay), ``/trajectory/commanded``, ``/events`` (collision starts
and ends) and the loop's outcome record, with the subject, controller, scenario settings and
body region in its session metadata. (A recorded session has more topics: the catalogue reads
only metadata and ``/events``, analysis only these two topics.) Written once, in a process pool,
under the system temp directory, keyed by this generator's version; a folder is complete when
its ``.complete`` marker is there.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from benchmarks.bench_replay import RATE_HZ, inputs
from hilrig import replay as api
from hilrig.recording import (
    ControllerSample,
    EventKind,
    EventRecord,
    JointSample,
    SessionInfo,
    SessionOutcome,
    SessionWriter,
    default_channels,
)
from hilrig.rig import AXIS_NAMES as AXES

VERSION = 1  # bump when the generator changes
SUBJECTS = 50
LAWS = ("adaptive", "fixed")
DURATION_S = 600
START_UTC_NS = 1_767_225_600_000_000_000


def study_root() -> Path:
    return Path(tempfile.gettempdir()) / f"hilrig-bench-study-v{VERSION}"


def subject_id(number: int) -> str:
    return f"S{number:03d}"


def session_path(root: Path, number: int, law: str) -> Path:
    return root / subject_id(number) / f"{subject_id(number)}-{law}.mcap"


def ensure_study(root: Path) -> float | None:
    """Write the study into ``root`` unless it is complete; the seconds it took (None: it was
    there)."""
    marker = root / ".complete"
    if marker.exists():
        return None
    start = time.perf_counter()
    shutil.rmtree(root, ignore_errors=True)
    jobs = [(number, law) for number in range(1, SUBJECTS + 1) for law in LAWS]
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(os.cpu_count() or 1, mp_context=context) as pool:
        list(pool.map(write_one, [root] * len(jobs), *zip(*jobs, strict=True)))
    marker.write_text("")
    return time.perf_counter() - start


def write_one(root: Path, number: int, law: str, *, duration_s: int = DURATION_S) -> Path:
    """Subject ``number``'s session under ``law`` (see the module doc)."""
    path = session_path(root, number, law)
    path.parent.mkdir(parents=True, exist_ok=True)
    ticks = duration_s * RATE_HZ
    scale = 0.6 + (number % 11) / 10.0
    force, torque = inputs(number, ticks)
    f = scale * np.hstack([force, torque])
    t_s = np.arange(ticks) / RATE_HZ
    state = api.run(api.ForceTrace(t_s, f, AXES, "bench", 1.0 / RATE_HZ), api.parse_specs([law]))
    columns = {
        name: state[[f"{name}_{a}" for a in AXES]].to_numpy().tolist()
        for name in ("offset", "velocity", "damping", "stiffness", "zeta", "contact")
    }
    info = SessionInfo(
        session_id=path.stem,
        subject_id=subject_id(number),
        rig="emulated",
        controller=law,
        start_utc_ns=START_UTC_NS + number * 3_600_000_000_000,
        start_monotonic_ns=1_000_000_000,
        scenario="paper-end-effector",
        scenario_settings={"scale": scale, "period_s": 30.0},
        body_region="hand",
    )
    partial = path.with_suffix(f".{os.getpid()}.partial")
    partial.unlink(missing_ok=True)
    period_ns = 1_000_000_000 // RATE_HZ
    before = 0
    writer = SessionWriter(partial, info, channels=default_channels(controller=law))
    write = writer.write
    rows = zip(
        f.tolist(),
        *(columns[c] for c in ("offset", "velocity", "damping", "stiffness", "zeta")),
        columns["contact"],
        strict=True,
    )
    for i, (fi, e, ed, b, k, zeta, contact) in enumerate(rows):
        t = info.start_monotonic_ns + i * period_ns
        write("/controller/state", ControllerSample(t, fi, e, ed, b, k, zeta, zeta, contact))
        write("/trajectory/commanded", JointSample(t, e[3:]))
        if contact[0] != before and contact[0] in (0, 1):
            kind = EventKind.COLLISION_START if contact[0] == 1 else EventKind.COLLISION_END
            write("/events", EventRecord(t, kind, "controller", "", "end effector"))
        before = contact[0]
    writer.close(_outcome(ticks).to_metadata())
    partial.rename(path)
    return path


def _outcome(ticks: int) -> SessionOutcome:
    return SessionOutcome(ticks, 0, 0, 0, 0, 0, "", 20.0, 60.0, 25.0, 45.0, 120.0, 300.0)
