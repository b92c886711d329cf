"""Small synthetic studies for the study tests: sessions written with hilrig's own writer.

Each session is the paper's collision (both experiments) scaled by the subject's own factor,
through the session's controller, at 500 Hz, with a ``/events`` log and the loop's outcome
record: so subjects differ, controllers differ, and every number can be checked.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hilrig.control import PAPER_DT_S
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

sys.path.insert(0, str(Path(__file__).parents[1] / "analysis"))
from analysis_helpers import CARTESIAN, JOINTS, paper_inputs, simulate_all

START_UTC_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00:00Z


def outcome(
    ticks: int, *, drops: int = 0, holds: int = 0, missed: int = 0, ended_by: str = ""
) -> SessionOutcome:
    """A session's end figures ("" ended_by: as an older hilrig wrote it)."""
    return SessionOutcome(
        ticks=ticks,
        hold_ticks=holds,
        fallback_ticks=0,
        missed_deadlines=missed,
        merged_frames=0,
        recorder_drops=drops,
        ended_by=ended_by,
        lateness_p50_us=10.0,
        lateness_p99_us=50.0,
        compute_p50_us=20.0,
        compute_p99_us=40.0,
        sensor_to_command_p50_us=100.0,
        sensor_to_command_p99_us=200.0,
    )


def write_study_session(
    path: Path,
    *,
    subject: str,
    law: str,
    scale: float,
    session_id: str,
    duration_s: float = 8.0,
    drops: int = 0,
    finished: bool = True,
    settings: dict[str, object] | None = None,
    ended_by: str = "",
) -> Path:
    """One session: the paper's inputs x ``scale`` through ``law`` (see the module doc)."""
    t_s, force, torque = paper_inputs(duration_s, PAPER_DT_S)
    columns = simulate_all(law, PAPER_DT_S, scale * force, scale * torque)
    axes = CARTESIAN + JOINTS
    matrix = {q: np.column_stack([columns[a][q] for a in axes]) for q in columns["x"]}
    start_mono = 5_000_000_000
    info = SessionInfo(
        session_id=session_id,
        subject_id=subject,
        rig="emulated",
        controller=law,
        start_utc_ns=START_UTC_NS,
        start_monotonic_ns=start_mono,
        scenario="paper-end-effector",
        scenario_settings=settings or {"scale": scale},
        body_region="hand",
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = SessionWriter(path, info, channels=default_channels(controller=law))
    contact = matrix["contact"][:, 0]
    for n, t in enumerate(t_s):
        t_ns = start_mono + round(t * 1e9)
        writer.write(
            "/controller/state",
            ControllerSample(
                t_ns,
                matrix["force"][n],
                matrix["offset"][n],
                matrix["velocity"][n],
                matrix["damping"][n],
                matrix["stiffness"][n],
                np.zeros(len(axes)),
                matrix["zeta"][n],
                [int(c) for c in matrix["contact"][n]],
            ),
        )
        writer.write("/trajectory/commanded", JointSample(t_ns, matrix["offset"][n, 3:]))
        if n and contact[n] == 1 and contact[n - 1] != 1:
            event = EventRecord(t_ns, EventKind.COLLISION_START, "controller", "", "end effector")
            writer.write("/events", event)
    ended = outcome(len(t_s), drops=drops, ended_by=ended_by)
    writer.close(ended.to_metadata() if finished else None)
    return path


def write_study(
    root: Path,
    subjects: Sequence[str],
    laws: Sequence[str],
    *,
    scales: Sequence[float] | None = None,
    duration_s: float = 8.0,
) -> list[Path]:
    """Every subject x law as ``root/<subject>/<subject>-<law>.mcap`` (session id the same)."""
    factors = scales or [1.0 + 0.25 * i for i in range(len(subjects))]
    written = []
    for subject, scale in zip(subjects, factors, strict=True):
        for law in laws:
            name = f"{subject}-{law}"
            path = root / subject / f"{name}.mcap"
            written.append(
                write_study_session(
                    path,
                    subject=subject,
                    law=law,
                    scale=scale,
                    session_id=name,
                    duration_s=duration_s,
                )
            )
    return written
