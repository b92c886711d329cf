"""The default layout of a hilrig view.

Left: the robot with the desired, actual and per-run end trajectories and the force arrow in
3D, above the event log and the "about" note. Right, in tabs: forces, joints and contact states;
then one tab per controller quantity (offset e, damping b, stiffness k, zeta) with a plot per
axis and one line per run. Every plot's time axis is linked, so zooming one zooms all.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb
from rerun.blueprint.components import LinkAxis

from hilrig.viz import paths
from hilrig.viz.decimate import Decimation

CARTESIAN = ("x", "y", "z")
_LINKED = rrb.TimeAxis(link=LinkAxis.LinkToGlobal)


def blueprint(axis_names: Sequence[str], decimation: Decimation | None = None) -> rrb.Blueprint:
    """The layout for a session with ``axis_names``; plot titles say when (and how much) the
    display is decimated."""
    note = ""
    if decimation is not None and decimation.active:
        note = f" [display decimated {decimation.factor:.0f}x]"

    def plot(origin: str, name: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(origin=origin, name=name + note, axis_x=_LINKED)

    overview = rrb.Vertical(
        plot(paths.INPUT, "controller input (N, N*m)"),
        plot(paths.WRIST, "wrist F/T as measured, sensor frame (N, N*m)"),
        plot(paths.JOINTS, "joint angles (rad)"),
        rrb.StateTimelineView(origin=paths.CONTACT, name="contact state (per run and group)"),
        name="forces and joints",
    )
    quantity_tabs = []
    for quantity, (title, cartesian_unit, joint_unit) in paths.QUANTITIES.items():
        views = [
            plot(
                paths.quantity_axis(quantity, axis),
                f"{title} {axis} ({cartesian_unit if axis in CARTESIAN else joint_unit})",
            )
            for axis in axis_names
        ]
        quantity_tabs.append(rrb.Grid(*views, grid_columns=3, name=title))
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=paths.WORLD, name="robot and end trajectories (m)"),
        rrb.Tabs(
            rrb.TextLogView(origin=paths.EVENTS, name="events"),
            rrb.TextDocumentView(origin=paths.ABOUT, name="about this view"),
        ),
        row_shares=[3, 1],
    )
    right = rrb.Tabs(overview, *quantity_tabs)
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[2, 3]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=paths.TIMELINE),
    )
