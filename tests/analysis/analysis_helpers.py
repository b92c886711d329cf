"""Inputs for the analysis tests: the paper scenario as a replay table, and small sessions.

The replay table follows the replay contract (one row per run and tick; ``run``, ``law``,
``t_s``, then force/offset/velocity/damping/stiffness/zeta/contact per axis; schema metadata
``hilrig.runs``), built here from ``hilrig.control.simulate`` until the replay engine exists.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from hilrig.control import PAPER_DT_S, simulate
from hilrig.paper.profiles import end_effector_force, joint_torque
from hilrig.recording import (
    ControllerSample,
    JointSample,
    SessionInfo,
    SessionWriter,
    SplitPolicy,
    default_channels,
)

CARTESIAN = ("x", "y", "z")
JOINTS = tuple(f"joint{j}" for j in range(1, 7))
PAPER_LAWS = ("adaptive", "variable-stiffness", "fixed")
START_UTC_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00:00Z
START_MONO_NS = 5_000_000_000


def paper_inputs(duration_s: float = 10.0, dt_s: float = PAPER_DT_S) -> tuple[np.ndarray, ...]:
    """(t_s, end-effector force (T, 3) N, joint torque (T, 6) N*m) of section 3.4."""
    t_s = np.arange(round(duration_s / dt_s), dtype=np.float64) * dt_s
    return t_s, end_effector_force(t_s), joint_torque(t_s)


def simulate_all(law: str, dt_s: float, force: np.ndarray, torque: np.ndarray) -> dict[str, dict]:
    """Per axis name: force, offset, velocity, damping, stiffness, zeta, contact columns."""
    columns: dict[str, dict] = {}
    for axes, inputs, preset in (
        (CARTESIAN, force, "paper-end-effector"),
        (JOINTS, torque, "paper-joint"),
    ):
        result = simulate(law, inputs, dt_s, preset)
        zeta = result.zeta
        for k, axis in enumerate(axes):
            columns[axis] = {
                "force": inputs[:, k],
                "offset": result.offset[:, k],
                "velocity": result.velocity[:, k],
                "damping": result.damping[:, k],
                "stiffness": result.stiffness[:, k],
                "zeta": zeta[:, k],
                "contact": result.contact[:, k],
            }
    return columns


def paper_replay_frame(
    laws: Sequence[str] = PAPER_LAWS, duration_s: float = 10.0, dt_s: float = PAPER_DT_S
) -> pd.DataFrame:
    """The section 3.4 inputs (both experiments at once) through ``laws``, as a replay table."""
    t_s, force, torque = paper_inputs(duration_s, dt_s)
    frames = []
    for law in laws:
        data: dict[str, object] = {"run": law, "law": law, "t_s": t_s}
        for axis, columns in simulate_all(law, dt_s, force, torque).items():
            for quantity, values in columns.items():
                data[f"{quantity}_{axis}"] = values
        frames.append(pd.DataFrame(data))
    frame = pd.concat(frames, ignore_index=True)
    return frame.astype({f"contact_{a}": np.int8 for a in CARTESIAN + JOINTS})


def write_replay(path: Path, frame: pd.DataFrame) -> Path:
    """``frame`` as a replay result file, with the ``hilrig.runs`` schema metadata."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    runs = {
        run: {"law": law, "params": {}} for run, law in zip(frame["run"], frame["law"], strict=True)
    }
    metadata = {**(table.schema.metadata or {}), b"hilrig.runs": json.dumps(runs).encode()}
    pq.write_table(table.replace_schema_metadata(metadata), path)
    return path


def write_session(
    path: Path,
    *,
    subject_id: str,
    session_id: str,
    law: str = "adaptive",
    duration_s: float = 8.0,
    split_s: float | None = None,
) -> Path:
    """A session of the paper's inputs through ``law`` at 500 Hz: controller states and joint
    targets (a slow sweep of joint 1, 0.1 rad/s, faster while the offset moves it)."""
    dt_s = PAPER_DT_S
    t_s, force, torque = paper_inputs(duration_s, dt_s)
    columns = simulate_all(law, dt_s, force, torque)
    axes = CARTESIAN + JOINTS
    matrix = {q: np.column_stack([columns[a][q] for a in axes]) for q in columns["x"]}
    chi = np.tanh(matrix["force"] ** 2)
    joints = np.zeros((t_s.shape[0], 6))
    joints[:, 0] = 0.1 * t_s + matrix["offset"][:, 3]
    info = SessionInfo(
        session_id=session_id,
        subject_id=subject_id,
        rig="emulated",
        controller=law,
        start_utc_ns=START_UTC_NS,
        start_monotonic_ns=START_MONO_NS,
        controller_params={"preset": "paper"},
    )
    split = SplitPolicy(max_duration_s=split_s) if split_s is not None else None
    with SessionWriter(path, info, channels=default_channels(controller=law), split=split) as w:
        for n, t in enumerate(t_s):
            t_ns = START_MONO_NS + round(t * 1e9)
            w.write(
                "/controller/state",
                ControllerSample(
                    t_ns,
                    matrix["force"][n],
                    matrix["offset"][n],
                    matrix["velocity"][n],
                    matrix["damping"][n],
                    matrix["stiffness"][n],
                    chi[n],
                    matrix["zeta"][n],
                    [int(c) for c in matrix["contact"][n]],
                ),
            )
            w.write("/trajectory/commanded", JointSample(t_ns, joints[n]))
    return path
