"""What the live-view tests share: the entities a live view logs, and reading a saved view back."""

from __future__ import annotations

import warnings
from pathlib import Path

from rrd_helpers import Rrd

from hilrig.rig import AXIS_NAMES
from hilrig.viz import paths
from hilrig.viz.scene import RECORDED

GROUPS = ("end effector", "body")
SERIES = (
    {paths.input_series(a) for a in AXIS_NAMES}
    | {paths.run_series(q, a, RECORDED) for q in paths.QUANTITIES for a in AXIS_NAMES}
    | {paths.wrist_series(c) for c in paths.WRIST_CHANNELS}
    | {paths.joint_series(f"joint{j + 1}") for j in range(6)}
)
LIVE_ENTITIES = (
    SERIES
    | {paths.contact_lane(g, RECORDED) for g in GROUPS}
    | {paths.ROBOT_LINKS, paths.ROBOT_JOINTS, paths.FORCE_ARROW, paths.EVENTS}
    | {
        f"{folder}/now"
        for folder in (
            paths.trajectory(paths.DESIRED),
            paths.trajectory(paths.ACTUAL),
            paths.run_trajectory(RECORDED),
        )
    }
)


def read(path: Path) -> Rrd:
    with warnings.catch_warnings():  # `rerun --save` writes no footer: read it whole
        warnings.simplefilter("ignore")
        return Rrd(path)
