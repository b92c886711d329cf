"""A session and its replays in one view: the scene, its layout and the note that explains it."""

from __future__ import annotations

import os
from dataclasses import dataclass

import rerun as rr
import rerun.blueprint as rrb

from hilrig.viz import paths, style
from hilrig.viz.blueprint import blueprint
from hilrig.viz.decimate import Decimation
from hilrig.viz.log import (
    DEFAULT_MAX_POINTS,
    DEFAULT_MAX_POSES,
    FORCE_SCALE_M_PER_N,
    Logged,
    log_scene,
    run_styles,
)
from hilrig.viz.scene import Scene
from hilrig.viz.sinks import APPLICATION_ID


@dataclass(frozen=True)
class ViewReport:
    """What was shown: the runs in their colours and how much the display was thinned."""

    runs: tuple[tuple[str, str], ...]  # (label, #rrggbb)
    logged: Logged


def about(scene: Scene, decimation: Decimation, max_poses: int) -> str:
    """The view's note (Markdown): source, runs and colours, timeline, decimation."""
    runs = run_styles(scene.runs)
    lines = [f"# {scene.source}", ""]
    if scene.session is not None:
        s = scene.session
        lines += [f"Session `{s.session_id}`, subject `{s.subject_id}`, rig `{s.rig}`.", ""]
    lines += [
        f"{len(scene.t_s)} control ticks, {scene.duration_s:.3f} s. Timeline `{paths.TIMELINE}`:"
        " s from the first control tick.",
        "",
        "Runs (one colour each in every view):",
        "",
        *(f"- `{style.hex_color(r.color)}` {r.label}" for r in runs),
        "",
        "3D: desired X_d (grey), actual from the measured joints (white), each run's reference"
        f" X_d + e (its colour); the force arrow draws {FORCE_SCALE_M_PER_N * 1000:g} mm per N.",
        "",
    ]
    if scene.notes:
        lines += ["**Problems reading the file** (what is shown is what could be read):", ""]
        lines += [f"- {note}" for note in scene.notes]
        lines.append("")
    if decimation.active:
        lines.append(
            f"**Display decimated**: each series shows at most {decimation.points} of its"
            f" {decimation.samples} samples (the minimum and maximum of every bucket, so peaks"
            f" stay); 3D poses at most {max_poses}, at each bucket's largest force. The data in"
            " the file is untouched; `--max-points 0` shows every sample."
        )
    else:
        lines.append("Every sample is shown (no decimation).")
    return "\n".join(lines)


def layout(scene: Scene, max_points: int = DEFAULT_MAX_POINTS) -> rrb.Blueprint:
    """The default blueprint of ``scene`` (its plot titles say if the display is decimated)."""
    return blueprint(scene.axis_names, Decimation.of(len(scene.t_s), max_points))


def show_scene(
    rec: rr.RecordingStream,
    scene: Scene,
    *,
    max_points: int = DEFAULT_MAX_POINTS,
    max_poses: int = DEFAULT_MAX_POSES,
) -> ViewReport:
    """Send ``scene`` and its note to ``rec`` (opened with :func:`layout` as its blueprint),
    thinned for display to ``max_points`` per series and ``max_poses`` in 3D (0: all)."""
    decimation = Decimation.of(len(scene.t_s), max_points)
    note = rr.TextDocument(about(scene, decimation, max_poses), media_type=rr.MediaType.MARKDOWN)
    rec.log(paths.ABOUT, note, static=True)
    logged = log_scene(rec, scene, max_points=max_points, max_poses=max_poses)
    runs = tuple((r.label, style.hex_color(r.color)) for r in run_styles(scene.runs))
    return ViewReport(runs, logged)


def save_rrd(
    scene: Scene,
    path: str | os.PathLike[str],
    *,
    max_points: int = DEFAULT_MAX_POINTS,
    max_poses: int = DEFAULT_MAX_POSES,
) -> ViewReport:
    """Write the view of ``scene`` to a new ``.rrd`` file, layout included.

    Rerun encodes the view in memory and hilrig writes the file, so a disk that refuses it
    raises OSError here (Rerun's own file sink logs such a failure to the terminal, and
    reports it without its reason)."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id(scene))
    stream = rr.binary_stream(recording=rec)
    try:
        rec.send_blueprint(layout(scene, max_points), make_active=False, make_default=True)
        report = show_scene(rec, scene, max_points=max_points, max_poses=max_poses)
        with open(path, "xb") as out:
            out.write(stream.read(flush=True) or b"")
    finally:
        rec.disconnect()
    return report


def recording_id(scene: Scene) -> str | None:
    """The session's id, so that views of one session share a recording in the viewer."""
    return scene.session.session_id if scene.session is not None else None
