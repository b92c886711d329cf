"""What a recorded session says about the world the robot met: per collision a fitted contact
model (:func:`hilrig.world.contact.fit_contact`), the arm's response to its commands
(:func:`hilrig.world.response.fit_response`), and the loop's recorded inputs the closed-loop
replay runs on (tick times, controller input, desired pose, start joints).

A collision is a run of ticks whose Cartesian controller input exceeds ``EVENT_LOW_SHARE`` of
the session's peak (and ``EVENT_MIN_N``) and somewhere ``EVENT_SHARE`` of it (a hysteresis: a
yielding robot may let the force of one collision fall low before it ends), runs closer than
``EVENT_MERGE_S`` merged, each widened by ``EVENT_PAD_S`` (at most to the middle between two).
The tool's position is the forward kinematics of the joint states interpolated to the tick; the
contact point is where the force's line passes nearest the sensor's origin (from the recorded
moment: ``r = F x M / |F|^2``), its median over the contact phase, in the sensor frame.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import partial
from multiprocessing import get_all_start_methods, get_context
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from hilrig.errors import ParameterError, RecordingError, ReplayError
from hilrig.recording import read
from hilrig.recording.schema import AXIS_NAMES
from hilrig.replay.engine import local_cores
from hilrig.replay.inputs import SessionIndex, session_index, trace_from_state
from hilrig.replay.recorded_holds import recorded_flags
from hilrig.replay.trace import ForceTrace
from hilrig.robot import RobotModel
from hilrig.robot.kinematics import CompiledChain, fk_into
from hilrig.world.contact import ContactFit, Mechanics, fit_contact
from hilrig.world.response import EMULATED_BANDWIDTH_RAD_S, ServoResponse, fit_response

EVENT_SHARE = 0.1
EVENT_LOW_SHARE = 0.02
EVENT_MIN_N = 0.5
EVENT_MERGE_S = 1.0  # a robot that yields, leaves the body and comes back: one collision
EVENT_PAD_S = 0.3
CLOCK_WINDOW_S = 10.0  # the robot clock's offset is taken per window this long
POOL_MIN_COLLISIONS = 4  # fitted in a process pool from this many (about 0.5 s each)

STATE, JOINTS, COMMANDED, DESIRED, INPUT, EVENTS = (
    "/controller/state",
    "/joint_states",
    "/trajectory/commanded",
    "/trajectory/desired",
    "/controller/input",
    "/events",
)
Array = NDArray[np.float64]


@dataclass(frozen=True)
class Collision:
    """One collision: its ticks ``[start, stop)``, the contact fit over them, the tool's
    position at the contact's onset (base, m; where the surface's travel is measured from) and
    the contact point in the sensor frame (m)."""

    name: str
    start: int
    stop: int
    fit: ContactFit
    reference_m: tuple[float, float, float]
    point_in_sensor_m: tuple[float, float, float]

    @property
    def mechanics(self) -> Mechanics:
        return self.fit.model.mechanics


@dataclass(frozen=True)
class SessionWorld:
    """A recording's loop inputs and the world fitted to it (arrays one row per tick)."""

    trace: ForceTrace  # the recorded controller input (9 axes) and the ticks' times
    position_d: Array  # (n, 3) desired TCP position, base, m
    rotation_d: Array  # (n, 3, 3) desired TCP rotation, base
    orientation_d: Array  # (n, 4) its quaternion (w, x, y, z)
    q_start_rad: Array  # (6,) measured joints at the first tick
    contact_rec_m: Array  # (n, 3) each collision's contact point, recorded motion, base, m
    link_flags: NDArray[np.int64]  # (n,) the live tick's link flags (recorded_holds.py)
    response: ServoResponse
    collisions: tuple[Collision, ...]
    emulated: bool
    index: SessionIndex  # the recording's topics, session and outcome records

    @property
    def t_s(self) -> Array:
        """The ticks' times from the first, s."""
        return self.trace.t_s

    @property
    def sensor_to_command_us(self) -> tuple[float, float] | None:
        """The loop's recorded sensor-to-command p50 and p99 (us), when the file has them."""
        outcome = self.index.outcome
        if outcome is None:
            return None
        return outcome.sensor_to_command_p50_us, outcome.sensor_to_command_p99_us

    def reach(self, index: int) -> slice:
        """The ticks collision ``index``'s model applies to: from its start to the next's."""
        following = self.collisions[index + 1].start if index + 1 < len(self.collisions) else None
        return slice(self.collisions[index].start, following or len(self.t_s))


def load_world(
    path: Path, model: RobotModel, *, mechanics: Mechanics | None = None
) -> SessionWorld:
    """Read ``path`` and fit its world; ``mechanics`` forces one contact model on every collision
    (None: the better fit). Raises ReplayError (one line) for a recording that lacks what the
    closed loop needs or a collision that cannot be fitted."""
    index = session_index(path)
    try:
        frames = read(path, [STATE, JOINTS, COMMANDED, DESIRED, INPUT, EVENTS]).frames
    except RecordingError as err:
        raise ReplayError(str(err)) from err
    for topic in (STATE, JOINTS, COMMANDED, DESIRED):
        if topic not in frames or len(frames[topic]) == 0:
            raise ReplayError(f"{path}: no {topic}: a closed-loop replay needs the loop's record")
    state, joints = frames[STATE], frames[JOINTS]
    trace = trace_from_state(path, state, index)
    if trace.axis_names != AXIS_NAMES:
        raise ReplayError(
            f"{path}: the closed loop needs the live loop's axes {', '.join(AXIS_NAMES)};"
            f" {STATE} has {', '.join(trace.axis_names)}"
        )
    t0 = int(state.index[0])
    t_s, force = trace.t_s, trace.force
    desired = frames[DESIRED]
    position_d = desired[[f"pose.position.{a}" for a in "xyz"]].to_numpy(np.float64)
    orientation_d = desired[[f"pose.orientation.{a}" for a in "wxyz"]].to_numpy(np.float64)
    rotation_d = _rotations(orientation_d)
    q_measured = _columns(joints, "position", 6, path)
    t_joints = (sample_times_ns(joints) - t0) / 1e9
    order = np.argsort(t_joints, kind="stable")
    t_joints, q_measured = t_joints[order], q_measured[order]
    latest = np.maximum(np.searchsorted(t_joints, t_s, side="right") - 1, 0)
    chain = CompiledChain.from_model(model)
    # where the arm was at each tick: the joint states interpolated (a sample-and-hold would
    # put steps into the travel's rate, which the contact's damping turns into force spikes)
    at_ticks = np.stack([np.interp(t_s, t_joints, q_measured[:, j]) for j in range(6)], 1)
    poses = _poses(chain, at_ticks)
    moment = (
        frames[INPUT][[f"wrench.torque.{a}" for a in "xyz"]].to_numpy(np.float64)
        if INPUT in frames and len(frames[INPUT]) == len(state)
        else np.zeros((len(state), 3))
    )
    emulated = index.session is not None and index.session.rig == "emulated"
    after = t_joints >= 0.0
    commanded = frames[COMMANDED]
    try:
        response = fit_response(
            (commanded.index.to_numpy() - t0) / 1e9,
            _columns(commanded, "position", 6, path),
            t_joints[after],
            q_measured[after],
            model.limits,
            bandwidth_rad_s=EMULATED_BANDWIDTH_RAD_S if emulated else None,
        )
    except ParameterError as err:
        raise ReplayError(f"{path}: {err}") from err
    contact_rec = poses[:, :3, 3].copy()
    windows = collision_windows(t_s, force[:, :3])
    names, points = [], []
    for number, (start, stop) in enumerate(windows, 1):
        names.append(f"{path.name} collision {number} at {t_s[start]:.2f} s")
        window = slice(start, stop)
        points.append(_contact_point(force[window, :3], moment[window], poses[window]))
        # the closed loop applies a collision's model until the next one starts
        reach = slice(start, windows[number][0] if number < len(windows) else len(t_s))
        contact_rec[reach] = poses[reach, :3, 3] + poses[reach, :3, :3] @ points[-1]
    inputs = [(t_s[a:b], force[a:b, :3], contact_rec[a:b], mechanics) for a, b in windows]
    collisions = []
    for name, (start, stop), point, fit in zip(
        names, windows, points, _fits(names, inputs), strict=True
    ):
        onset = start + int(np.searchsorted(t_s[start:stop], fit.t_on_s))
        reference = tuple(float(v) for v in contact_rec[onset])
        collisions.append(Collision(name, start, stop, fit, reference, tuple(point)))  # type: ignore[arg-type]
    return SessionWorld(
        trace,
        position_d,
        rotation_d,
        orientation_d,
        np.ascontiguousarray(q_measured[latest[0]]),
        contact_rec,
        recorded_flags(state.index.to_numpy(np.int64), frames.get(EVENTS)),
        response,
        tuple(collisions),
        emulated,
        index,
    )


FitInput = tuple[Array, Array, Array, Mechanics | None]


def _fit(arguments: FitInput) -> ContactFit:
    t_s, force, tool, mechanics = arguments
    return fit_contact(t_s, force, tool, mechanics=mechanics)


def _fits(names: Sequence[str], inputs: Sequence[FitInput]) -> list[ContactFit]:
    """Each collision's fit, in forked processes once there are ``POOL_MIN_COLLISIONS``; raises
    ReplayError (one line, naming the collision) for one that cannot be fitted."""
    workers = min(local_cores(), len(inputs))
    if workers > 1 and len(inputs) >= POOL_MIN_COLLISIONS and "fork" in get_all_start_methods():
        with ProcessPoolExecutor(workers, mp_context=get_context("fork")) as pool:
            return _named(names, [pool.submit(_fit, arguments).result for arguments in inputs])
    return _named(names, [partial(_fit, arguments) for arguments in inputs])


def _named(names: Sequence[str], fits: Sequence[Callable[[], ContactFit]]) -> list[ContactFit]:
    """Each fit, its ParameterError as ReplayError naming its collision."""
    done = []
    for name, fit in zip(names, fits, strict=True):
        try:
            done.append(fit())
        except ParameterError as err:
            raise ReplayError(f"{name}: {err}") from err
    return done


def sample_times_ns(joints: pd.DataFrame) -> NDArray[np.int64]:
    """When each joint state was sampled, on the log clock (ns): the robot's own timestamp
    (``publish_time``) plus the clock offset: the least receive delay of each ``CLOCK_WINDOW_S``
    window, taken at the state that had it and interpolated between them (the offset may drift
    slowly). The receive (log) times bunch
    when the loop reads several states at once, which would put false steps into the arm's
    motion. A recording without the robot's timestamps keeps its log times."""
    log_ns = joints.index.to_numpy().astype(np.int64)
    device_ns = joints["publish_time_ns"].to_numpy().astype(np.int64)
    if len(log_ns) < 2 or np.array_equal(log_ns, device_ns):
        return log_ns
    delay = log_ns - device_ns
    since = log_ns - log_ns[0]
    span = int(CLOCK_WINDOW_S * 1e9)
    window = since // span
    if window[-1] > 0 and since[-1] - window[-1] * span < span // 2:
        window[window == window[-1]] -= 1  # too short a last window: join it to the one before
    at, least = [], []
    for w in np.unique(window):
        members = np.flatnonzero(window == w)
        fastest = members[int(np.argmin(delay[members]))]
        at.append(float(since[fastest]))
        least.append(float(delay[fastest]))
    x = since.astype(np.float64)
    offset = np.interp(x, at, least)
    if len(at) > 1:  # beyond the first and last: along the drift of the nearest two
        first = (least[1] - least[0]) / (at[1] - at[0])
        last = (least[-1] - least[-2]) / (at[-1] - at[-2])
        offset = np.where(x < at[0], least[0] + first * (x - at[0]), offset)
        offset = np.where(x > at[-1], least[-1] + last * (x - at[-1]), offset)
    times: NDArray[np.int64] = device_ns + np.round(offset).astype(np.int64)
    return times


def collision_windows(t_s: Array, force_n: Array) -> list[tuple[int, int]]:
    """The ticks ``[start, stop)`` of each collision in a Cartesian force (n, 3) (module doc)."""
    magnitude = np.linalg.norm(force_n, axis=1)
    peak = float(magnitude.max(initial=0.0))
    high = max(EVENT_SHARE * peak, EVENT_MIN_N)
    above = np.flatnonzero(magnitude > max(EVENT_LOW_SHARE * peak, EVENT_MIN_N))
    if len(above) == 0 or peak <= high:
        return []
    merged: list[list[int]] = [[int(above[0]), int(above[0]) + 1]]
    for k in above[1:]:
        if t_s[k] - t_s[merged[-1][1] - 1] <= EVENT_MERGE_S:
            merged[-1][1] = int(k) + 1
        else:
            merged.append([int(k), int(k) + 1])
    runs = [run for run in merged if magnitude[run[0] : run[1]].max() > high]
    windows = []
    for i, (start, stop) in enumerate(runs):
        low = t_s[start] - EVENT_PAD_S
        high = t_s[stop - 1] + EVENT_PAD_S
        if i > 0:
            low = max(low, (t_s[runs[i - 1][1] - 1] + t_s[start]) / 2)
        if i + 1 < len(runs):
            high = min(high, (t_s[stop - 1] + t_s[runs[i + 1][0]]) / 2)
        windows.append((int(np.searchsorted(t_s, low)), int(np.searchsorted(t_s, high, "right"))))
    return windows


def _columns(frame: pd.DataFrame, name: str, count: int, path: Path) -> Array:
    wanted = [f"{name}_{i}" for i in range(count)]
    missing = [c for c in wanted if c not in frame]
    if missing:
        raise ReplayError(f"{path}: no {', '.join(missing)} in the recording")
    values = frame[wanted].to_numpy(np.float64)
    if not np.isfinite(values).all():
        row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise ReplayError(f"{path}: {name} at message {row} is not finite")
    return values


def _rotations(quaternion_wxyz: Array) -> Array:
    w, x, y, z = (quaternion_wxyz[:, i] for i in range(4))
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


def _poses(chain: CompiledChain, q_rad: Array) -> Array:
    poses = np.empty((len(q_rad), 4, 4))
    for k in range(len(q_rad)):
        fk_into(chain.frames, chain.axes, np.ascontiguousarray(q_rad[k]), poses[k])
    return poses


def _contact_point(force_n: Array, moment_nm: Array, poses: Array) -> NDArray[np.float64]:
    """Median over the strong half of the contact of ``F x M / |F|^2`` in the sensor frame."""
    squared = np.einsum("ij,ij->i", force_n, force_n)
    strong = squared >= 0.25 * squared.max(initial=0.0)
    if not strong.any() or squared.max(initial=0.0) == 0.0:
        return np.zeros(3)
    lever_base = np.cross(force_n[strong], moment_nm[strong]) / squared[strong, None]
    lever_sensor = np.einsum("kji,kj->ki", poses[strong, :3, :3], lever_base)
    point: NDArray[np.float64] = np.median(lever_sensor, axis=0)
    return point
