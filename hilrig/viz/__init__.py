"""Viewing: sessions, their replays and live sessions in the Rerun viewer.

    scene = scene_from_session("session.mcap", parse_specs(["fixed", "adaptive"]))
    save_rrd(scene, "session.rrd")                       # or open_stream(Sink(...), layout(scene))

Everything is logged with Rerun's columnar API (``send_columns``), thinned for display only
(:mod:`.decimate`); the entity tree is in :mod:`.paths`, the layout in :mod:`.blueprint`, the
live view of ``hilrig record --view`` in :mod:`.live`. ``docs/viewing.md`` shows the views.
"""

from hilrig.errors import ViewError
from hilrig.viz.blueprint import blueprint
from hilrig.viz.decimate import Decimation, minmax_indices, peak_indices
from hilrig.viz.log import DEFAULT_MAX_POINTS, DEFAULT_MAX_POSES, Logged, log_scene
from hilrig.viz.scene import RECORDED, RunCurves, Scene, scene_from_session
from hilrig.viz.sinks import Sink, SinkKind, WebServer, open_stream
from hilrig.viz.style import run_colors
from hilrig.viz.view import ViewReport, about, layout, recording_id, save_rrd, show_scene

__all__ = [
    "DEFAULT_MAX_POINTS",
    "DEFAULT_MAX_POSES",
    "RECORDED",
    "Decimation",
    "Logged",
    "RunCurves",
    "Scene",
    "Sink",
    "SinkKind",
    "ViewError",
    "ViewReport",
    "WebServer",
    "about",
    "blueprint",
    "layout",
    "log_scene",
    "minmax_indices",
    "open_stream",
    "peak_indices",
    "recording_id",
    "run_colors",
    "save_rrd",
    "scene_from_session",
    "show_scene",
]
