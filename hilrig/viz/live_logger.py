"""The live view's logger: :class:`~hilrig.rig.view_feed.ViewBatch` es onto the entity tree of
a file's view (:mod:`.paths`), the recorded controller as the run ``recorded``.

It runs in the viewer-feed process (:mod:`.live_feed`); :mod:`.live` is the session's end.
"""

from __future__ import annotations

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hilrig.recording.samples import EventRecord
from hilrig.rig import AXIS_NAMES, VIEW_RATE_HZ, Rows, ViewBatch
from hilrig.robot.model import RobotModel
from hilrig.viz import paths, style
from hilrig.viz.blueprint import blueprint
from hilrig.viz.decimate import Decimation
from hilrig.viz.log import (
    FORCE_SCALE_M_PER_N,
    RunStyle,
    latest_at,
    log_styles,
    send_contact,
    send_events,
    send_force,
    send_marker,
    send_robot,
    send_scalars,
)
from hilrig.viz.scene import RECORDED, group_columns
from hilrig.viz.scene import event_line as scene_event_line
from hilrig.viz.sinks import Sink, open_stream

FloatArray = NDArray[np.float64]


def about_live(*, session_id: str, controller: str, source: str, rate_hz: float) -> str:
    """The live view's note (Markdown)."""
    run = style.hex_color(style.run_colors([RECORDED])[RECORDED])
    return "\n".join(
        [
            f"# Live: session `{session_id}`",
            "",
            f"Streamed by `hilrig record` while it records `{source}`.",
            "",
            f"**Display decimated**: every stream is shown at {rate_hz:g} Hz (the first sample"
            f" of every {1000 / rate_hz:g} ms), every event as it comes. The file holds every"
            f" sample: `hilrig view {source}` shows it after the session.",
            "",
            f"Timeline `{paths.TIMELINE}`: s from the first control tick.",
            "",
            f"- `{run}` {RECORDED} ({controller})",
            "",
            "3D: where the desired X_d (grey), the actual end from the measured joints (white)"
            f" and the controller's reference X_d + e (`{run}`) are now; the force arrow draws"
            f" {FORCE_SCALE_M_PER_N * 1000:g} mm per N.",
        ]
    )


def _groups() -> dict[str, int]:
    """``{group label: the column whose contact state the group shares}``."""
    return {label: cols[0] for label, cols in group_columns(AXIS_NAMES).items()}


class LiveLogger:
    """Logs :class:`~hilrig.rig.view_feed.ViewBatch` es to ``rec`` on the entity tree of a
    file's view, as the run ``recorded``: forces, controller quantities, contact lanes, joints,
    wrist F/T, events, and in 3D the robot, the force arrow and where each end trajectory is now
    (no whole-path lines). Carries each contact lane's last state and the last joint angles from
    batch to batch."""

    def __init__(self, rec: rr.RecordingStream, model: RobotModel) -> None:
        self.rec = rec
        self.model = model
        self.groups = _groups()
        self.contact: dict[str, int | None] = dict.fromkeys(self.groups)
        self.q_rad: FloatArray | None = None  # the last joint angles seen
        self.batches = 0

    def log(self, batch: ViewBatch) -> None:
        """Send ``batch`` (times: s from its ``t0_ns``)."""
        t0_ns, rec = batch.t0_ns, self.rec
        if len(batch.ticks):
            t_ticks = _seconds(batch.ticks, t0_ns)
            self._controller(t_ticks, batch.ticks)
            self._space(t_ticks, batch.ticks, batch.joints)
        t_ft = _seconds(batch.ft, t0_ns)
        for c, channel in enumerate(paths.WRIST_CHANNELS):
            send_scalars(rec, paths.wrist_series(channel), t_ft, _col(batch.ft, "wrench", c))
        t_joints = _seconds(batch.joints, t0_ns)
        for j in range(6):
            q_rad = _col(batch.joints, "q", j)
            send_scalars(rec, paths.joint_series(f"joint{j + 1}"), t_joints, q_rad)
        if len(batch.joints):
            self.q_rad = np.array(batch.joints["q"][-1], dtype=np.float64)
        lines = [event_line(e) for e in batch.events]
        t_events = np.array([(e.t_ns - t0_ns) / 1e9 for e in batch.events], dtype=np.float64)
        send_events(rec, t_events, [text for text, _ in lines], [lvl for _, lvl in lines])
        self.batches += 1

    def _controller(self, t_s: FloatArray, ticks: Rows) -> None:
        """Per axis the input and the controller's quantities; the contact lanes."""
        for i, axis in enumerate(AXIS_NAMES):
            send_scalars(self.rec, paths.input_series(axis), t_s, _col(ticks, "force", i))
            for quantity in paths.QUANTITIES:  # TICK_DTYPE's own field names
                path = paths.run_series(quantity, axis, RECORDED)
                send_scalars(self.rec, path, t_s, _col(ticks, quantity, i))
        for group, column in self.groups.items():
            codes = np.ascontiguousarray(ticks["contact"][:, column])
            lane = paths.contact_lane(group, RECORDED)
            self.contact[group] = send_contact(self.rec, lane, t_s, codes, self.contact[group])

    def _space(self, t_s: FloatArray, ticks: Rows, joints: Rows) -> None:
        """Where X_d and X_d + e are; the robot, its TCP and the force arrow there (m, N)."""
        rec = self.rec
        desired = np.asarray(ticks["desired_position"], dtype=np.float64)
        send_marker(rec, f"{paths.trajectory(paths.DESIRED)}/now", t_s, desired)
        reference = desired + ticks["offset"][:, :3]
        send_marker(rec, f"{paths.run_trajectory(RECORDED)}/now", t_s, reference)
        q_rad = self._joints_at(ticks["t_ns"], joints)
        if q_rad is None:
            return
        links = np.array([self.model.link_points(q) for q in q_rad])
        send_robot(rec, t_s, links)
        send_marker(rec, f"{paths.trajectory(paths.ACTUAL)}/now", t_s, links[:, -1])
        send_force(rec, t_s, links[:, -1], np.asarray(ticks["force"][:, :3], dtype=np.float64))

    def _joints_at(self, t_ns: NDArray[np.int64], joints: Rows) -> FloatArray | None:
        """The latest joint angles (N, 6) at or before each of ``t_ns``: this batch's rows, the
        previous batch's last before them (the first row before anything); None without any."""
        t_joints, q_rad = joints["t_ns"], np.asarray(joints["q"], dtype=np.float64)
        if self.q_rad is not None:
            t_joints = np.concatenate(([np.iinfo(np.int64).min], t_joints))
            q_rad = np.vstack((self.q_rad, q_rad))
        if len(t_joints) == 0:
            return None
        return np.ascontiguousarray(latest_at(t_joints, q_rad, t_ns))


def _seconds(rows: Rows, t0_ns: int) -> FloatArray:
    return (rows["t_ns"] - t0_ns).astype(np.float64) / 1e9


def _col(rows: Rows, field: str, column: int) -> FloatArray:
    return np.ascontiguousarray(rows[field][:, column], dtype=np.float64)


def event_line(record: EventRecord) -> tuple[str, str]:
    """An event's line of text (as in a file's view) and its Rerun text-log level."""
    return scene_event_line(record.kind, record.source, record.detail, record.axis, record.value)


def open_live(
    sink: Sink,
    *,
    session_id: str,
    controller: str,
    source: str,
    rate_hz: float = VIEW_RATE_HZ,
    loop_rate_hz: float = 1000.0,
    urdf: str | None = None,
) -> LiveLogger:
    """A stream to ``sink`` with the live layout, styles and note sent, and its logger.
    Raises ViewError."""
    decimation = Decimation(round(loop_rate_hz), round(rate_hz))
    rec, _ = open_stream(sink, blueprint(AXIS_NAMES, decimation), recording_id=session_id)
    color = style.run_colors([RECORDED])[RECORDED]
    run = RunStyle(RECORDED, f"{RECORDED} ({controller})", color)
    log_styles(rec, AXIS_NAMES, [run], list(_groups()))
    note = about_live(session_id=session_id, controller=controller, source=source, rate_hz=rate_hz)
    rec.log(paths.ABOUT, rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)
    return LiveLogger(rec, RobotModel(urdf))
