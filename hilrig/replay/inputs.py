"""Replay inputs: an MCAP session or a CSV/Parquet table, read into one typed force trace.

From an MCAP session the trace is exactly what the controller saw: the ``force_*`` columns of
``/controller/state`` (all nine axes); a recording without it falls back to
``/controller/input`` (the compensated wrist force, x, y, z) plus, when present, the joint
torques of ``/joint_states`` (the latest one at or before each tick, as the loop takes them).
The period is the recorded loop's (``rate_hz`` of the session's controller parameters), else
the median interval. Tables (CSV, Parquet) are read by :mod:`.tables`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.errors import RecordingError, ReplayError
from hilrig.recording import SessionInfo, read
from hilrig.recording.info import outcome_of
from hilrig.recording.outcome import SessionOutcome
from hilrig.recording.scan import index_file
from hilrig.replay.specs import GROUP_AXES
from hilrig.replay.tables import trace_from_table
from hilrig.replay.trace import ForceTrace

PathLike = str | os.PathLike[str]
#: ``progress(done, total)``: chunks read so far, of all.
LoadProgress = Callable[[int, int], None]

STATE_TOPIC = "/controller/state"
INPUT_TOPIC = "/controller/input"
JOINT_TOPIC = "/joint_states"
MCAP_SUFFIXES = (".mcap",)
TABLE_SUFFIXES = (".csv", ".parquet", ".pq")


def load_trace(
    path: PathLike, *, resample: bool = False, progress: LoadProgress | None = None
) -> ForceTrace:
    """The force trace in ``path`` (``.mcap``, ``.csv``, ``.parquet``).

    ``resample`` lets a table with non-uniform times (or rows with missing force values) be
    interpolated onto a uniform grid (see :mod:`.tables`). ``progress(done, total)`` follows
    an MCAP file's chunks. Raises ReplayError (one line naming the file, and for tables the
    column and row) when the input cannot be replayed.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in MCAP_SUFFIXES:
        return trace_from_mcap(p, progress=progress)
    if suffix in TABLE_SUFFIXES:
        return trace_from_table(p, resample=resample)
    known = ", ".join(MCAP_SUFFIXES + TABLE_SUFFIXES)
    raise ReplayError(f"{p}: unknown input type {suffix or '(no suffix)'!r}; known: {known}")


@dataclass(frozen=True)
class SessionIndex:
    """What an MCAP file offers a replay: its topics and its session record (if any)."""

    topics: frozenset[str]
    session: SessionInfo | None
    controller_params: Mapping[str, object]
    outcome: SessionOutcome | None = None  # the loop's end figures, when recorded and readable


def session_index(path: Path) -> SessionIndex:
    """Topics and session metadata of ``path``, from its summary (nothing is decompressed)."""
    try:
        index = index_file(path)
        session = index.session_info()
    except RecordingError as err:
        raise ReplayError(str(err)) from err
    params = session.controller_params if session is not None else {}
    topics = frozenset(c.topic for c in index.channels.values())
    return SessionIndex(topics, session, params, outcome_of(index)[0])


def recorded_dt(path: Path, index: SessionIndex, log_ns: NDArray[np.int64]) -> float:
    """The recorded loop's period, s: ``1 / rate_hz`` of the session's controller parameters,
    else the median interval of ``log_ns``."""
    rate = index.controller_params.get("rate_hz")
    if rate is not None:
        try:
            rate_hz = float(str(rate))
        except ValueError:
            raise ReplayError(f"{path}: controller rate_hz {rate!r} is not a number") from None
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ReplayError(f"{path}: controller rate_hz {rate_hz} must be > 0")
        return 1.0 / rate_hz
    if len(log_ns) < 2:
        raise ReplayError(f"{path}: one tick and no rate_hz in the metadata: no period")
    return float(np.median(np.diff(log_ns))) / 1e9


def trace_from_mcap(path: Path, *, progress: LoadProgress | None = None) -> ForceTrace:
    """The controller input of a recorded session (see the module docstring)."""
    index = session_index(path)
    if STATE_TOPIC in index.topics:
        wanted = [STATE_TOPIC]
    elif INPUT_TOPIC in index.topics:
        wanted = [INPUT_TOPIC, *([JOINT_TOPIC] if JOINT_TOPIC in index.topics else [])]
    else:
        raise ReplayError(
            f"{path}: no {STATE_TOPIC} or {INPUT_TOPIC} to replay "
            f"(has {', '.join(sorted(index.topics)) or 'no topics'})"
        )
    try:
        loaded = read(path, wanted, progress=progress)
    except RecordingError as err:
        raise ReplayError(str(err)) from err
    frames = loaded.frames
    if STATE_TOPIC in frames:
        trace = trace_from_state(path, frames[STATE_TOPIC], index)
    else:
        trace = _from_input(path, frames[INPUT_TOPIC], frames.get(JOINT_TOPIC), index)
    return replace(trace, notes=trace.notes + loaded.problems)


def trace_from_state(path: Path, state: pd.DataFrame, index: SessionIndex) -> ForceTrace:
    """The ``force_*`` columns of a ``/controller/state`` frame, named by its ``axis_names``."""
    log_ns = _log_times(path, state, STATE_TOPIC)
    count = sum(1 for c in state.columns if str(c).startswith("axis_names_"))
    names = tuple(str(state[f"axis_names_{i}"].iloc[0]) for i in range(count))
    force = np.empty((len(state), count))
    for i in range(count):
        force[:, i] = state[f"force_{i}"].to_numpy()
    return _trace(path, STATE_TOPIC, log_ns, force, names, index)


def _from_input(
    path: Path, wrench: pd.DataFrame, joints: pd.DataFrame | None, index: SessionIndex
) -> ForceTrace:
    log_ns = _log_times(path, wrench, INPUT_TOPIC)
    names = GROUP_AXES["cartesian"]
    source = INPUT_TOPIC
    efforts = [f"effort_{i}" for i in range(len(GROUP_AXES["joint"]))]
    with_joints = joints is not None and len(joints) > 0 and all(c in joints for c in efforts)
    force = np.empty((len(wrench), len(names) + (len(efforts) if with_joints else 0)))
    for i, axis in enumerate("xyz"):
        force[:, i] = wrench[f"wrench.force.{axis}"].to_numpy()
    if with_joints:
        assert joints is not None
        joint_ns = joints.index.to_numpy()
        # the latest joint state at or before each tick; ticks before the first take the first
        latest = np.maximum(np.searchsorted(joint_ns, log_ns, side="right") - 1, 0)
        for j, column in enumerate(efforts):
            force[:, len(names) + j] = joints[column].to_numpy()[latest]
        names = names + GROUP_AXES["joint"]
        source = f"{INPUT_TOPIC} + {JOINT_TOPIC} effort"
    return _trace(path, source, log_ns, force, names, index)


def _log_times(path: Path, frame: pd.DataFrame, topic: str) -> NDArray[np.int64]:
    if len(frame) == 0:
        raise ReplayError(f"{path}: {topic} has no messages")
    log_ns: NDArray[np.int64] = frame.index.to_numpy()
    return log_ns


def _trace(
    path: Path,
    source: str,
    log_ns: NDArray[np.int64],
    force: NDArray[np.float64],
    names: tuple[str, ...],
    index: SessionIndex,
) -> ForceTrace:
    bad = ~np.isfinite(force)
    if bad.any():
        n, i = np.unravel_index(int(np.argmax(bad)), force.shape)
        raise ReplayError(
            f"{path}: {source}: force of axis {names[i]} at message {n} is {force[n, i]}"
        )
    t_s = (log_ns - log_ns[0]).astype(np.float64) / 1e9
    dt_s = recorded_dt(path, index, log_ns)
    return ForceTrace(t_s, force, names, f"{path}:{source}", dt_s, int(log_ns[0]), index.session)
