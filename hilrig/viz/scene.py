"""What a view shows, as arrays: a recorded session and the runs of its controllers.

:func:`scene_from_session` reads a session file once (the topics a view needs), takes the
recorded controller's curves from ``/controller/state`` and replays its exact input through any
further controllers. Times are s from the session's first control tick (the replay results'
``t_s``); every topic shares that zero.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.errors import RecordingError, ReplayError, ViewError
from hilrig.recording import EventKind, SessionInfo, read
from hilrig.replay import ControllerSpec, Run, load_results, replay
from hilrig.replay.inputs import STATE_TOPIC, session_index, trace_from_state
from hilrig.replay.specs import GROUP_AXES

FloatArray = NDArray[np.float64]
PathLike = str | os.PathLike[str]

RECORDED = "recorded"
GROUP_LABELS = {"cartesian": "end effector", "joint": "body"}
TOPICS = (
    STATE_TOPIC,
    "/joint_states",
    "/trajectory/desired",
    "/ft/wrist",
    "/events",
    "/robot_description",
)
_EVENT_LEVELS = {
    EventKind.COLLISION_START: "WARN",
    EventKind.COLLISION_END: "INFO",
    EventKind.RECOVERED: "INFO",
    EventKind.FAULT: "ERROR",
    EventKind.OPERATOR_MARK: "INFO",
}


@dataclass(frozen=True)
class RunCurves:
    """One controller's response: (T, A) arrays over the scene's ticks, axes in its order.
    ``contact`` holds ContactState codes (each axis carries its group's state)."""

    name: str
    label: str
    offset: FloatArray
    damping: FloatArray
    stiffness: FloatArray
    zeta: FloatArray
    contact: NDArray[np.int8]

    def quantity(self, name: str) -> FloatArray:
        """``offset``, ``damping``, ``stiffness`` or ``zeta``."""
        values: FloatArray = getattr(self, name)
        return values


@dataclass(frozen=True)
class Series:
    """Samples of a topic: ``t_s`` (N,) and ``values`` (N, C)."""

    t_s: FloatArray
    values: FloatArray

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True)
class Events:
    """Discrete events: time (s), one line of text and a Rerun text-log level each."""

    t_s: FloatArray
    text: tuple[str, ...]
    level: tuple[str, ...]


@dataclass(frozen=True)
class Scene:
    """Everything a view of one session shows.

    ``t_s`` (T,) the control ticks; ``force`` (T, A) the controller input per axis of
    ``axis_names`` (N, N*m); ``runs`` the recorded controller first, then the replays, all on
    those ticks. ``desired`` (X_d position, m, base frame), ``joints`` (measured q, rad) and
    ``wrist`` (F/T as measured, sensor frame) are None where the file has none; ``notes`` are
    the problems met reading the file (a truncated end, a corrupt chunk), shown with the view.
    """

    source: str
    axis_names: tuple[str, ...]
    t_s: FloatArray
    force: FloatArray
    runs: tuple[RunCurves, ...]
    desired: Series | None = None
    joints: Series | None = None
    wrist: Series | None = None
    events: Events = field(default_factory=lambda: Events(np.empty(0), (), ()))
    urdf: str | None = None
    session: SessionInfo | None = None
    start_ns: int = 0
    notes: tuple[str, ...] = ()  # problems met reading the file (truncation, bad chunks)

    @property
    def groups(self) -> dict[str, tuple[int, ...]]:
        """``{group label: column indices}`` of the axis groups present."""
        return group_columns(self.axis_names)

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0


def scene_from_session(
    path: PathLike,
    controllers: Sequence[ControllerSpec] = (),
    results: Sequence[PathLike] = (),
) -> Scene:
    """The scene of the session in ``path`` with the recorded controller, ``controllers``
    replayed on its recorded input and the runs of replay result tables ``results`` (written by
    ``hilrig replay --out X.parquet`` from this session). Raises ViewError (one line naming the
    file)."""
    p = Path(path)
    if p.suffix.lower() != ".mcap":
        raise ViewError(f"{p}: not a session file (.mcap)")
    try:
        index = session_index(p)
        if STATE_TOPIC not in index.topics:
            raise ViewError(f"{p}: no {STATE_TOPIC}: nothing to view (is it a hilrig session?)")
        loaded = read(p, [t for t in TOPICS if t in index.topics])
        state = loaded.frames[STATE_TOPIC]
        trace = trace_from_state(p, state, index)
        runs = [Run.from_spec(spec, trace.axis_names) for spec in controllers]
        table = replay(trace, runs) if runs else None
        stored = [(Path(r), *load_results(r)) for r in results]
    except (RecordingError, ReplayError) as err:
        raise ViewError(str(err)) from err
    replays = _replay_curves(table, [r.name for r in runs], trace.axis_names, trace.ticks)
    for result_path, result, recorded_runs in stored:
        _check_same_input(result_path, result, trace.t_s, trace.axis_names)
        replays += _replay_curves(result, list(recorded_runs), trace.axis_names, trace.ticks)
    names = [RECORDED, *(r.name for r in replays)]
    twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
    if twice is not None:
        raise ViewError(
            f"{p}: two runs are named {twice!r} (runs: {', '.join(names)}); name a controller"
            " with NAME=LAW"
        )
    frames = loaded.frames
    t0_ns = int(state.index[0])
    controller = str(state["controller"].iloc[0]) if "controller" in state else "?"
    recorded = _recorded_curves(state, len(trace.axis_names), f"{RECORDED} ({controller})")
    return Scene(
        source=str(p),
        axis_names=trace.axis_names,
        t_s=_seconds(state, t0_ns),
        force=trace.force,
        runs=(recorded, *replays),
        desired=_series(frames, "/trajectory/desired", t0_ns, "pose.position.", "xyz"),
        joints=_series(frames, "/joint_states", t0_ns, "position_", "012345"),
        wrist=_wrist(frames, t0_ns),
        events=_events(frames.get("/events"), t0_ns),
        urdf=_urdf(frames.get("/robot_description")),
        session=index.session,
        start_ns=t0_ns,
        notes=loaded.problems,
    )


def _seconds(frame: pd.DataFrame, t0_ns: int) -> FloatArray:
    log_ns = frame.index.to_numpy(dtype=np.int64)
    return (log_ns - t0_ns).astype(np.float64) / 1e9


def _columns(frame: pd.DataFrame, names: Sequence[str]) -> FloatArray:
    out = np.empty((len(frame), len(names)))
    for i, name in enumerate(names):
        out[:, i] = frame[name].to_numpy(dtype=np.float64)
    return out


def _recorded_curves(state: pd.DataFrame, axes: int, label: str) -> RunCurves:
    def block(prefix: str) -> FloatArray:
        return _columns(state, [f"{prefix}_{i}" for i in range(axes)])

    contact = np.empty((len(state), axes), dtype=np.int8)
    for i in range(axes):
        contact[:, i] = state[f"contact_state_{i}"].to_numpy()
    return RunCurves(
        RECORDED,
        label,
        block("offset"),
        block("damping"),
        block("stiffness"),
        block("zeta"),
        contact,
    )


def _replay_curves(
    table: pd.DataFrame | None, names: Sequence[str], axes: Sequence[str], ticks: int
) -> list[RunCurves]:
    if table is None:
        return []
    out = []
    for k, name in enumerate(names):
        rows = slice(k * ticks, (k + 1) * ticks)  # the table is grouped by run, in order

        def block(prefix: str, rows: slice = rows) -> FloatArray:
            return _columns(table.iloc[rows], [f"{prefix}_{a}" for a in axes])

        contact = np.empty((ticks, len(axes)), dtype=np.int8)
        for i, a in enumerate(axes):
            contact[:, i] = table[f"contact_{a}"].to_numpy()[rows]
        law = str(table["law"].iloc[k * ticks])
        out.append(
            RunCurves(
                name,
                f"{name} ({law})",
                block("offset"),
                block("damping"),
                block("stiffness"),
                block("zeta"),
                contact,
            )
        )
    return out


def _check_same_input(
    path: Path, table: pd.DataFrame, t_s: FloatArray, axes: Sequence[str]
) -> None:
    """``table`` must be a replay of this session's input: same axes, ticks and times."""
    missing = [a for a in axes if f"offset_{a}" not in table]
    runs = table["run"].nunique()
    if missing or len(table) != runs * len(t_s):
        raise ViewError(
            f"{path}: not a replay of this session ({len(table)} rows for {runs} run(s), the "
            f"session has {len(t_s)} ticks{'; no axes ' + ', '.join(missing) if missing else ''})"
        )
    first = table["t_s"].to_numpy()[: len(t_s)]
    if not np.allclose(first, t_s, rtol=0.0, atol=1e-6):
        n = int(np.argmax(~np.isclose(first, t_s, rtol=0.0, atol=1e-6)))
        raise ViewError(
            f"{path}: not a replay of this session (tick {n} at {first[n]:.6f} s, the session's"
            f" at {t_s[n]:.6f} s)"
        )


def _series(
    frames: dict[str, pd.DataFrame], topic: str, t0_ns: int, prefix: str, suffixes: str
) -> Series | None:
    frame = frames.get(topic)
    names = [prefix + s for s in suffixes]
    if frame is None or len(frame) == 0 or not all(n in frame for n in names):
        return None
    return Series(_seconds(frame, t0_ns), _columns(frame, names))


def _wrist(frames: dict[str, pd.DataFrame], t0_ns: int) -> Series | None:
    frame = frames.get("/ft/wrist")
    names = [f"wrench.{part}.{a}" for part in ("force", "torque") for a in "xyz"]
    if frame is None or len(frame) == 0 or not all(n in frame for n in names):
        return None
    return Series(_seconds(frame, t0_ns), _columns(frame, names))


def _events(frame: pd.DataFrame | None, t0_ns: int) -> Events:
    if frame is None or len(frame) == 0:
        return Events(np.empty(0), (), ())
    lines = [
        event_line(int(kind), source, detail, axis, value)
        for kind, source, detail, axis, value in zip(
            frame["kind"].to_numpy(),
            frame["source"].astype(str),
            frame["detail"].astype(str),
            frame["axis"].astype(str),
            frame["value"].to_numpy(dtype=np.float64),
            strict=True,
        )
    ]
    return Events(
        _seconds(frame, t0_ns), tuple(t for t, _ in lines), tuple(level for _, level in lines)
    )


def event_line(kind: int, source: str, detail: str, axis: str, value: float) -> tuple[str, str]:
    """An event's line in the viewer's log (``[source] kind: axis, detail (value)``) and its
    Rerun text-log level."""
    try:
        code = EventKind(kind)
        name, level = code.name.lower().replace("_", " "), _EVENT_LEVELS[code]
    except ValueError:
        name, level = f"event {kind}", "INFO"
    words = [w for w in (axis, detail) if w and w != "nan"]
    text = f"{name}: {', '.join(words)}" if words else name
    if not math.isnan(value):
        text += f" ({value:g})"
    return f"[{source}] {text}", level


def group_columns(axis_names: Sequence[str]) -> dict[str, tuple[int, ...]]:
    """``{group label: column indices}`` of the axis groups present in ``axis_names``."""
    out: dict[str, tuple[int, ...]] = {}
    for group, axes in GROUP_AXES.items():
        cols = tuple(axis_names.index(a) for a in axes if a in axis_names)
        if cols:
            out[GROUP_LABELS[group]] = cols
    return out


def _urdf(frame: pd.DataFrame | None) -> str | None:
    if frame is None or len(frame) == 0 or "data" not in frame:
        return None
    return str(frame["data"].iloc[0])
