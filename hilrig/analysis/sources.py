"""What analysis reads: controller runs from recorded sessions (MCAP) and replay results (Parquet).

A :class:`Run` is one controller's response to a force input, as arrays; a :class:`Source` is
one input with every run that saw it (a session: one run, the controller that was live; a replay
result: one run per controller). Times are s from the input's first sample; forces N or N*m,
offsets m or rad, offset rates m/s or rad/s, commanded joints rad.

Replay results follow the replay table contract: one row per (run, tick) with ``run``, ``law``,
``t_s`` and, per axis present, ``force_<axis>``, ``offset_<axis>``, ``velocity_<axis>`` (plus
damping, stiffness, zeta and contact columns analysis does not need).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from hilrig.analysis.events import CARTESIAN_AXES, JOINT_AXES, FloatArray
from hilrig.errors import AnalysisError
from hilrig.recording import SessionInfo, inspect, load
from hilrig.recording.session import SESSION_METADATA, validate_subject_id
from hilrig.recording.session_ids import written_as

STATE_TOPIC = "/controller/state"
COMMANDED_TOPIC = "/trajectory/commanded"
KNOWN_AXES = CARTESIAN_AXES + JOINT_AXES
SESSION_SUFFIX, REPLAY_SUFFIX = ".mcap", ".parquet"
INPUT_KEY = b"hilrig.input"  # replay tables: where the input came from (JSON)


@dataclass(frozen=True)
class Run:
    """One controller's response to a force input.

    ``t_s`` (T,) increasing, s; ``force``, ``offset``, ``offset_rate`` (T, A), one column per
    name in ``axes`` (N or N*m; m or rad; m/s or rad/s). ``offset[n]`` is the offset commanded at
    tick n, which belongs to the next tick's time (docs/analysis.md: e[n] = e(t_n + dt)).
    ``commanded_t_s`` (C,) and ``commanded_joints_rad`` (C, 6) are the joint targets sent to the
    robot, when recorded. Raises AnalysisError for mismatched shapes or times that go back.
    """

    name: str
    law: str
    axes: tuple[str, ...]
    t_s: FloatArray
    force: FloatArray
    offset: FloatArray
    offset_rate: FloatArray
    commanded_t_s: FloatArray | None = None
    commanded_joints_rad: FloatArray | None = None

    def __post_init__(self) -> None:
        shape = (self.t_s.shape[0], len(self.axes))
        for name in ("force", "offset", "offset_rate"):
            if getattr(self, name).shape != shape:
                raise AnalysisError(f"run {self.name}: {name} is not {shape}")
        if self.t_s.shape[0] < 2 or np.any(np.diff(self.t_s) <= 0):
            raise AnalysisError(f"run {self.name}: needs two or more strictly increasing times")
        unknown = sorted(set(self.axes) - set(KNOWN_AXES))
        if unknown:
            raise AnalysisError(f"run {self.name}: unknown axes {unknown}")


class SourceKind(StrEnum):
    """Where a source came from."""

    SESSION = "session"  # a recorded MCAP session
    REPLAY = "replay"  # a replay result table


@dataclass(frozen=True)
class Source:
    """One force input and every run that saw it.

    ``subject_id`` and ``session_id`` say which recorded session the force input comes from (a
    session's own; a replay's as its ``hilrig.input`` metadata says, None if it does not);
    ``session`` is the whole metadata of a recorded session; ``start_ns`` the log time of
    t_s = 0, ns since the Unix epoch, when known.
    """

    path: Path
    kind: SourceKind
    runs: tuple[Run, ...]
    subject_id: str | None = None
    session_id: str | None = None
    session: SessionInfo | None = None
    start_ns: int | None = None
    body_region: str = ""  # the recorded ISO/TS 15066 region ("" none)
    contact_area_cm2: float | None = None  # the recorded contact area (None: not given)

    @property
    def name(self) -> str:
        """The file's path as given (the first part's, for a split session)."""
        return str(self.path)


def load_session(paths: Path | Sequence[Path]) -> Source:
    """A recorded session (the parts of a split session, in order) as a one-run source.

    The run is named after the session's controller; time 0 is the first controller state.
    Raises AnalysisError (one line naming the file) if it has no session metadata or no
    controller states, RecordingError if it cannot be read.
    """
    parts = [paths] if isinstance(paths, Path) else list(paths)
    info = inspect(parts[0])
    session = info.session_info()
    if session is None:
        raise AnalysisError(f"{parts[0]}: no session metadata; is it a hilrig recording?")
    counts = {t.topic: t.count for t in info.topics}
    if not counts.get(STATE_TOPIC):
        raise AnalysisError(f"{parts[0]}: no {STATE_TOPIC} messages to analyse")
    topics = [STATE_TOPIC] + ([COMMANDED_TOPIC] if counts.get(COMMANDED_TOPIC) else [])
    frames = load(parts if len(parts) > 1 else parts[0], topics=topics)
    state = frames[STATE_TOPIC]
    axes = tuple(str(state[c].iloc[0]) for c in state.columns if c.startswith("axis_names_"))
    t0 = int(state.index[0])
    run = Run(
        name=session.controller,
        law=session.controller,
        axes=axes,
        t_s=_seconds(state.index, t0),
        force=_matrix(state, "force", len(axes)),
        offset=_matrix(state, "offset", len(axes)),
        offset_rate=_matrix(state, "offset_rate", len(axes)),
        **_commanded(frames.get(COMMANDED_TOPIC), t0),
    )
    return Source(
        parts[0],
        SourceKind.SESSION,
        (run,),
        subject_id=session.subject_id,
        session_id=session.session_id,
        session=session,
        start_ns=t0,
        body_region=session.body_region,
        contact_area_cm2=session.contact_area_cm2,
    )


def _seconds(index: pd.Index, t0_ns: int) -> FloatArray:
    return (index.to_numpy(dtype=np.int64) - t0_ns) / 1e9


def _matrix(frame: pd.DataFrame, field: str, count: int) -> FloatArray:
    return frame[[f"{field}_{i}" for i in range(count)]].to_numpy(dtype=np.float64)


def _commanded(frame: pd.DataFrame | None, t0_ns: int) -> dict[str, FloatArray | None]:
    """The joint targets in JOINT_AXES order; none unless all six joints are named."""
    columns = [f"name_{j}" for j in range(len(JOINT_AXES))]
    usable = frame is not None and frame.shape[0] > 1 and set(columns) <= set(frame.columns)
    names = [str(frame[c].iloc[0]) for c in columns] if frame is not None and usable else []
    if frame is None or sorted(names) != sorted(JOINT_AXES):
        return {"commanded_t_s": None, "commanded_joints_rad": None}
    order = [f"position_{names.index(joint)}" for joint in JOINT_AXES]
    return {
        "commanded_t_s": _seconds(frame.index, t0_ns),
        "commanded_joints_rad": frame[order].to_numpy(dtype=np.float64),
    }


def load_replay(path: Path) -> Source:
    """A replay result table as a source with one run per distinct ``run``, in first-seen order.

    The optional schema metadata ``hilrig.input`` (JSON) gives the recorded session the input
    came from (``subject_id``, ``session_id``, ``body_region``, ``contact_area_cm2``) and its
    ``t0_ns``. Raises AnalysisError naming
    the file if it cannot be read or breaks the table contract.
    """
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as err:
        raise AnalysisError(f"{path}: cannot read the replay table ({err})") from err
    try:
        runs = runs_from_frame(table.to_pandas())
        origin = json.loads((table.schema.metadata or {}).get(INPUT_KEY, b"{}"))
    except (AnalysisError, ValueError) as err:
        raise AnalysisError(f"{path}: {err}") from err
    subject_id, session_id, t0_ns = (origin.get(k) for k in ("subject_id", "session_id", "t0_ns"))
    area = origin.get("contact_area_cm2")
    return Source(
        path,
        SourceKind.REPLAY,
        runs,
        subject_id=None if subject_id is None else validate_subject_id(str(subject_id)),
        session_id=None if session_id is None else str(session_id),
        start_ns=None if t0_ns is None else int(t0_ns),
        body_region=str(origin.get("body_region") or ""),
        contact_area_cm2=None if area is None else float(area),
    )


def runs_from_frame(frame: pd.DataFrame) -> tuple[Run, ...]:
    """The runs of a replay table (see the module docstring), each sorted by ``t_s``."""
    missing = {"run", "law", "t_s"} - set(frame.columns)
    axes = tuple(a for a in KNOWN_AXES if f"force_{a}" in frame.columns)
    if missing or not axes:
        raise AnalysisError(f"not a replay table: missing {sorted(missing) or 'force_<axis>'}")
    needed = [f"{q}_{a}" for q in ("offset", "velocity") for a in axes]
    absent = [c for c in needed if c not in frame.columns]
    if absent:
        raise AnalysisError(f"not a replay table: missing {absent}")
    if frame.empty:
        raise AnalysisError("a replay table without rows")
    # pandas deep-copies a frame's attrs (a replay's run metadata) into every column taken from
    # it: once here, not once for each of the 27 columns of 9 axes
    frame = frame.copy(deep=False)
    frame.attrs = {}
    names = frame["run"].unique()
    groups = (
        [(names[0], frame)] if len(names) == 1 else frame.groupby("run", sort=False, observed=True)
    )
    return tuple(_run(str(name), rows, axes) for name, rows in groups)


def _run(name: str, rows: pd.DataFrame, axes: tuple[str, ...]) -> Run:
    """One run's rows as a Run, sorted by ``t_s`` (stable); only the arrays taken are copied,
    and not even those where the columns lie evenly spaced in one buffer (:func:`side_by_side`)."""
    t_s = rows["t_s"].to_numpy(dtype=np.float64)
    order = None if bool(np.all(t_s[1:] >= t_s[:-1])) else np.argsort(t_s, kind="stable")

    def block(quantity: str) -> FloatArray:
        columns = [rows[f"{quantity}_{a}"].to_numpy(dtype=np.float64) for a in axes]
        values = side_by_side(columns)
        if values is None:
            values = rows[[f"{quantity}_{a}" for a in axes]].to_numpy(dtype=np.float64)
        return values if order is None else values[order]

    return Run(
        name=name,
        law=str(rows["law"].iloc[0]),
        axes=axes,
        t_s=t_s if order is None else t_s[order],
        force=block("force"),
        offset=block("offset"),
        offset_rate=block("velocity"),
    )


def side_by_side(columns: Sequence[FloatArray]) -> FloatArray | None:
    """The (T, A) read-only view whose column i is ``columns[i]``, without a copy, when the
    columns are contiguous float64 arrays of one buffer at evenly spaced addresses (a replay's
    result table: each quantity's columns are rows of one block); else None.

    A replay table's run read this way rather than interleaved into new arrays saves three
    copies into fresh memory (130 MB for a 10-minute 9-axis run): its analysis went from 128
    to 90 ms by hand. The view keeps the first column's buffer, which holds them all, alive."""
    first = columns[0]
    ticks, root = first.shape[0], _root(first)
    plain = all(
        c.dtype == np.float64 and c.ndim == 1 and c.shape[0] == ticks and c.strides == (8,)
        for c in columns
    )
    if not plain or ticks == 0 or any(_root(c) is not root for c in columns):
        return None
    address = first.ctypes.data
    step = columns[1].ctypes.data - address if len(columns) > 1 else 8
    if any(c.ctypes.data != address + i * step for i, c in enumerate(columns)):
        return None
    view: FloatArray = np.lib.stride_tricks.as_strided(
        first, (ticks, len(columns)), (8, step), writeable=False
    )
    return view


def _root(array: np.ndarray) -> object:
    """The object that owns ``array``'s memory: the end of its chain of bases."""
    owner: object = array
    while isinstance(owner, np.ndarray) and owner.base is not None:
        owner = owner.base
    return owner


def find_inputs(paths: Iterable[Path], *, exclude: Path | None = None) -> list[Path]:
    """The files to analyse: each given file, and every .mcap/.parquet file under each folder.

    Files under ``exclude`` (an output folder) are skipped. Raises AnalysisError for a path
    that does not exist or a file of another kind, and when nothing is left.
    """
    skip = exclude.resolve() if exclude is not None else None
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            found += sorted(
                p for p in path.rglob("*") if p.suffix in (SESSION_SUFFIX, REPLAY_SUFFIX)
            )
        elif path.suffix in (SESSION_SUFFIX, REPLAY_SUFFIX) and path.is_file():
            found.append(path)
        else:
            raise AnalysisError(f"{path}: not an .mcap session, a .parquet replay or a folder")
    found = [p for p in found if skip is None or not p.resolve().is_relative_to(skip)]
    if not found:
        raise AnalysisError("no .mcap sessions or .parquet replay results to analyse")
    return found


def load_sources(paths: Iterable[Path], *, exclude: Path | None = None) -> tuple[Source, ...]:
    """Every input under ``paths`` (see :func:`find_inputs`); the parts of a split session (same
    session id, named as its writer named them) are read as one session, and any other files
    as sessions of their own, whatever id they claim. Raises AnalysisError or RecordingError
    (one line) for input that cannot be read."""
    files = find_inputs(paths, exclude=exclude)
    sessions: dict[tuple[str, str], list[tuple[int, Path]]] = {}
    sources: list[Source | tuple[str, str]] = []  # a session's place, until all are seen
    for path in files:
        if path.suffix == REPLAY_SUFFIX:
            sources.append(load_replay(path))
            continue
        record = inspect(path).metadata.get(SESSION_METADATA, {})
        part = record.get("part", "0")
        number = int(part) if part.isdigit() else 0
        key = (record.get("session_id", ""), written_as(str(path), number))
        if key not in sessions:
            sessions[key] = []
            sources.append(key)
        sessions[key].append((number, path))
    return tuple(
        s if isinstance(s, Source) else load_session([p for _, p in sorted(sessions[s])])
        for s in sources
    )
