"""Columnar logging of a hilrig view: every entity in one ``send_columns`` call per batch.

The low-level ``send_*`` functions take arrays and are shared by the file views
(:func:`log_scene`) and the live view (:mod:`.live`); :func:`log_styles` sends the static
names and colours once. Times go on the ``time`` timeline, s from the first control tick.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hilrig.recording.samples import ContactState
from hilrig.robot.model import RobotModel
from hilrig.viz import paths, style
from hilrig.viz.decimate import Decimation, minmax_indices, peak_indices
from hilrig.viz.scene import RunCurves, Scene
from hilrig.world.body import REGIONS

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

FORCE_SCALE_M_PER_N = 0.005  # the force arrow: 20 N draws 10 cm
DEFAULT_MAX_POINTS = 20_000  # per time series
DEFAULT_MAX_POSES = 5_000  # robot poses, force arrows and trajectory markers
CONTACT_LABELS = {s: s.name.lower() for s in ContactState}
CARTESIAN = ("x", "y", "z")


@dataclass(frozen=True)
class RunStyle:
    """How a run appears: its entity name, its legend label and its colour."""

    name: str
    label: str
    color: style.RGB


@dataclass(frozen=True)
class Logged:
    """What :func:`log_scene` sent: the thinning of the longest series and of the 3D views."""

    series: Decimation
    poses: Decimation


def run_styles(runs: Sequence[RunCurves]) -> tuple[RunStyle, ...]:
    colors = style.run_colors([r.name for r in runs])
    return tuple(RunStyle(r.name, r.label, colors[r.name]) for r in runs)


def _time(t_s: FloatArray) -> list[rr.TimeColumn]:
    """The ``time`` column of ``t_s`` (s), rounded to the nanosecond (Rerun truncates s)."""
    duration = np.rint(np.asarray(t_s) * 1e9).astype("timedelta64[ns]")
    return [rr.TimeColumn(paths.TIMELINE, duration=duration)]


def send_scalars(rec: rr.RecordingStream, path: str, t_s: FloatArray, values: FloatArray) -> None:
    """One time series (N,) at times ``t_s`` (N,)."""
    rec.send_columns(path, indexes=_time(t_s), columns=rr.Scalars.columns(scalars=values))


def send_robot(rec: rr.RecordingStream, t_s: FloatArray, links: FloatArray) -> None:
    """Robot poses ``links`` (N, P, 3): per time, one polyline and its joint points."""
    n, p, _ = links.shape
    rec.send_columns(
        paths.ROBOT_LINKS, indexes=_time(t_s), columns=rr.LineStrips3D.columns(strips=list(links))
    )
    rec.send_columns(
        paths.ROBOT_JOINTS,
        indexes=_time(t_s),
        columns=rr.Points3D.columns(positions=links.reshape(n * p, 3)).partition([p] * n),
    )


def send_force(
    rec: rr.RecordingStream, t_s: FloatArray, origin_m: FloatArray, force_n: FloatArray
) -> None:
    """The force (N, 3) in N, base frame, as an arrow at ``origin_m`` (N, 3)."""
    rec.send_columns(
        paths.FORCE_ARROW,
        indexes=_time(t_s),
        columns=rr.Arrows3D.columns(vectors=force_n * FORCE_SCALE_M_PER_N, origins=origin_m),
    )


def send_marker(rec: rr.RecordingStream, path: str, t_s: FloatArray, position: FloatArray) -> None:
    """Where one trajectory (N, 3) is at each time: one point."""
    rec.send_columns(path, indexes=_time(t_s), columns=rr.Points3D.columns(positions=position))


def send_contact(
    rec: rr.RecordingStream,
    path: str,
    t_s: FloatArray,
    codes: NDArray[np.int8],
    previous: int | None = None,
) -> int | None:
    """The contact-state lane: a state change where ``codes`` (N,) differs from the state
    before (``previous``, None at the start). Returns the last state."""
    if len(codes) == 0:
        return previous
    changed = np.flatnonzero(
        np.diff(codes.astype(np.int64), prepend=-1 if previous is None else previous)
    )
    if len(changed):
        names = [_contact_name(int(c)) for c in codes[changed]]
        rec.send_columns(
            path, indexes=_time(t_s[changed]), columns=rr.StateChange.columns(state=names)
        )
    return int(codes[-1])


def send_events(
    rec: rr.RecordingStream, t_s: FloatArray, text: Sequence[str], level: Sequence[str]
) -> None:
    if len(t_s):
        rec.send_columns(
            paths.EVENTS,
            indexes=_time(t_s),
            columns=rr.TextLog.columns(text=list(text), level=list(level)),
        )


def _contact_name(code: int) -> str:
    try:
        return CONTACT_LABELS[ContactState(code)]
    except ValueError:
        return f"state {code}"


def log_styles(
    rec: rr.RecordingStream,
    axis_names: Sequence[str],
    runs: Sequence[RunStyle],
    groups: Sequence[str],
) -> None:
    """Static names and colours of every series, lane and 3D entity."""
    rec.log(paths.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log(
        paths.ROBOT_LINKS, rr.LineStrips3D.from_fields(colors=style.ROBOT, radii=0.012), static=True
    )
    rec.log(
        paths.ROBOT_JOINTS, rr.Points3D.from_fields(colors=style.ROBOT, radii=0.02), static=True
    )
    rec.log(
        paths.FORCE_ARROW, rr.Arrows3D.from_fields(colors=style.FORCE, radii=0.006), static=True
    )
    for axis in axis_names:
        color = style.AXIS_COLORS.get(axis, style.ACTUAL)
        unit = "N" if axis in CARTESIAN else "N*m"
        rec.log(
            paths.input_series(axis),
            _lines(color, f"{axis} ({unit})"),
            static=True,
        )
        for quantity in paths.QUANTITIES:
            for run in runs:
                rec.log(
                    paths.run_series(quantity, axis, run.name),
                    _lines(run.color, run.label),
                    static=True,
                )
    for i, channel in enumerate(paths.WRIST_CHANNELS):
        rec.log(
            paths.wrist_series(channel),
            _lines(style.AXIS_COLORS[CARTESIAN[i % 3]], channel),
            static=True,
        )
    for j in range(6):
        joint = f"joint{j + 1}"
        rec.log(
            paths.joint_series(joint),
            _lines(style.AXIS_COLORS[joint], f"{joint} (rad)"),
            static=True,
        )
    states = list(ContactState)
    contact_style = rr.StateConfiguration(
        values=[CONTACT_LABELS[s] for s in states],
        colors=[style.CONTACT_COLORS[s] for s in states],
    )
    for group in groups:
        for run in runs:
            rec.log(paths.contact_lane(group, run.name), contact_style, static=True)
    trajectories = [(paths.DESIRED, style.DESIRED), (paths.ACTUAL, style.ACTUAL)]
    for name, color in trajectories:
        _trajectory_style(rec, paths.trajectory(name), color)
    for run in runs:
        _trajectory_style(rec, paths.run_trajectory(run.name), run.color)


def _lines(color: style.RGB, name: str) -> rr.SeriesLines:
    """A series' legend and colour; zoomed out, the viewer draws each pixel column's min and
    max (not their mean), so peaks stay visible at every zoom, like the decimation."""
    return rr.SeriesLines(colors=color, names=name, aggregation_policy="MinMax")


def _trajectory_style(rec: rr.RecordingStream, folder: str, color: style.RGB) -> None:
    rec.log(f"{folder}/now", rr.Points3D.from_fields(colors=color, radii=0.01), static=True)


def log_scene(
    rec: rr.RecordingStream,
    scene: Scene,
    *,
    max_points: int = DEFAULT_MAX_POINTS,
    max_poses: int = DEFAULT_MAX_POSES,
    model: RobotModel | None = None,
) -> Logged:
    """Send ``scene`` to ``rec``: static styles and paths, then every series, lane, pose and
    event, each thinned to ``max_points`` (series) or ``max_poses`` (3D) for display only
    (0: everything). ``model`` (default: the file's URDF, else the packaged AUBO-i5) draws the
    robot. Returns how much was thinned."""
    runs = run_styles(scene.runs)
    log_styles(rec, scene.axis_names, runs, list(scene.groups))
    t = scene.t_s
    for i, axis in enumerate(scene.axis_names):
        _send_thinned(rec, paths.input_series(axis), t, scene.force[:, i], max_points)
        for run in scene.runs:
            for quantity in paths.QUANTITIES:
                path = paths.run_series(quantity, axis, run.name)
                _send_thinned(rec, path, t, run.quantity(quantity)[:, i], max_points)
    for label, cols in scene.groups.items():
        for run in scene.runs:
            send_contact(rec, paths.contact_lane(label, run.name), t, run.contact[:, cols[0]])
    for series, names in ((scene.wrist, paths.WRIST_CHANNELS), (scene.joints, None)):
        if series is None:
            continue
        for c in range(series.values.shape[1]):
            path = paths.wrist_series(names[c]) if names else paths.joint_series(f"joint{c + 1}")
            _send_thinned(rec, path, series.t_s, series.values[:, c], max_points)
    send_events(rec, scene.events.t_s, scene.events.text, scene.events.level)
    _log_limits(rec, scene, max_points)
    poses = _log_space(rec, scene, runs, max_points, max_poses, model)
    return Logged(Decimation.of(len(t), max_points), poses)


def _log_limits(rec: rr.RecordingStream, scene: Scene, max_points: int) -> None:
    """|F| and the session's body region's transient and quasi-static force limits as lines
    beside the controller input (nothing without a region or the Cartesian axes)."""
    region = REGIONS.get(scene.session.body_region) if scene.session is not None else None
    if region is None or not all(a in scene.axis_names for a in CARTESIAN) or len(scene.t_s) < 2:
        return
    xyz = [scene.axis_names.index(axis) for axis in CARTESIAN]
    rec.log(paths.FORCE_NORM, _lines(style.FORCE_NORM, "|F| (N)"), static=True)
    _send_thinned(rec, paths.FORCE_NORM, scene.t_s, np.linalg.norm(scene.force[:, xyz], axis=1),
                  max_points)  # fmt: skip
    ends = scene.t_s[[0, -1]]
    limits = {"transient": region.transient_force_n, "quasi_static": region.quasi_static_force_n}
    for phase, limit in limits.items():
        if limit is None:  # no transient contact is permitted there
            continue
        label = f"{phase.replace('_', '-')} limit, {region.name} (N)"
        rec.log(paths.limit_series(phase), _lines(style.LIMITS[phase], label), static=True)
        send_scalars(rec, paths.limit_series(phase), ends, np.full(2, limit))


def _send_thinned(
    rec: rr.RecordingStream, path: str, t_s: FloatArray, values: FloatArray, max_points: int
) -> None:
    """One series, thinned to ``max_points`` for display (:func:`minmax_indices`)."""
    column = np.ascontiguousarray(values)
    keep = minmax_indices(column, max_points)
    send_scalars(rec, path, t_s[keep], column[keep])


def _log_space(
    rec: rr.RecordingStream,
    scene: Scene,
    runs: Sequence[RunStyle],
    max_points: int,
    max_poses: int,
    model: RobotModel | None,
) -> Decimation:
    """The 3D view: paths (static, ``max_points``), the robot, the force arrow and a marker per
    trajectory (``max_poses``, at each bucket's largest force)."""
    t = scene.t_s
    if not all(a in scene.axis_names for a in CARTESIAN):
        return Decimation(len(t), 0)
    xyz = [scene.axis_names.index(a) for a in CARTESIAN]
    force = scene.force[:, xyz]
    magnitude = np.sqrt(np.einsum("ij,ij->i", force, force))
    path_keep = peak_indices(magnitude, max_points)
    pose_keep = peak_indices(magnitude, max_poses)
    if scene.desired is not None:
        desired = latest_at(scene.desired.t_s, scene.desired.values, t)
        _send_path(rec, paths.trajectory(paths.DESIRED), desired[path_keep], style.DESIRED)
        send_marker(rec, f"{paths.trajectory(paths.DESIRED)}/now", t[pose_keep], desired[pose_keep])
        for run, curves in zip(runs, scene.runs, strict=True):
            reference = desired + curves.offset[:, xyz]
            folder = paths.run_trajectory(run.name)
            _send_path(rec, folder, reference[path_keep], run.color)
            send_marker(rec, f"{folder}/now", t[pose_keep], reference[pose_keep])
    if scene.joints is not None:
        if model is None:
            model = RobotModel(scene.urdf) if scene.urdf else RobotModel()
        q = latest_at(scene.joints.t_s, scene.joints.values, t)
        tips = np.array([model.link_points(q[n])[-1] for n in path_keep])
        _send_path(rec, paths.trajectory(paths.ACTUAL), tips, style.ACTUAL)
        links = np.array([model.link_points(q[n]) for n in pose_keep])
        send_robot(rec, t[pose_keep], links)
        send_marker(rec, f"{paths.trajectory(paths.ACTUAL)}/now", t[pose_keep], links[:, -1])
        send_force(rec, t[pose_keep], links[:, -1], force[pose_keep])
    return Decimation(len(t), len(pose_keep))


def _send_path(rec: rr.RecordingStream, folder: str, points: FloatArray, color: style.RGB) -> None:
    rec.log(f"{folder}/path", rr.LineStrips3D([points], colors=color, radii=0.002), static=True)


def latest_at(t: NDArray[Any], values: FloatArray, at: NDArray[Any]) -> FloatArray:
    """``values`` of the latest sample at or before each time of ``at`` (the first sample for
    times before it); ``t`` ascending, both in one unit (s or ns)."""
    rows = np.maximum(np.searchsorted(t, at, side="right") - 1, 0)
    out: FloatArray = values[rows]
    return out
