"""Entity paths of a hilrig view: the same tree for a file and for a live session.

::

    /about                                  TextDocument: source, runs and colours, decimation
    /events                                 TextLog: collision, recovery, fault and mark events
    /world                                  3D, base frame, metres, z up
    /world/robot/links                      LineStrips3D: base -> joint origins -> TCP
    /world/robot/joints                     Points3D: the joint origins
    /world/force                            Arrows3D: the controller's force at the TCP
    /world/trajectory/<name>/path           LineStrips3D (static): desired X_d, actual (FK)
    /world/trajectory/<name>/now            Points3D: where that trajectory is at the time
    /world/trajectory/runs/<run>/{path,now} the same for each run's reference X_d + e
    /series/input/<axis>                    Scalars: the controller input, N or N*m
    /series/input/norm, /series/input/limit_{transient,quasi_static}
                                            Scalars: |F| and the body region's ISO/TS 15066
                                            limits (safety.md), when the session names one
    /series/wrist/<fx..mz>                  Scalars: the wrist F/T as measured (sensor frame)
    /series/joints/<joint>                  Scalars: measured joint angles, rad
    /series/<quantity>/<axis>/<run>         Scalars: offset, damping, stiffness, zeta
    /contact/<group>/<run>                  StateChange: Algorithm 2 state of an axis group

Run names and other parts are escaped (:func:`rerun.escape_entity_path_part`).
"""

from __future__ import annotations

from rerun import escape_entity_path_part

TIMELINE = "time"  # a duration: s from the session's first control tick

ABOUT = "/about"
EVENTS = "/events"
WORLD = "/world"
ROBOT_LINKS = "/world/robot/links"
ROBOT_JOINTS = "/world/robot/joints"
FORCE_ARROW = "/world/force"
TRAJECTORIES = "/world/trajectory"
INPUT = "/series/input"
WRIST = "/series/wrist"
JOINTS = "/series/joints"
SERIES = "/series"
CONTACT = "/contact"

#: The per-run quantities plotted per axis, with the unit of a Cartesian and of a joint axis.
QUANTITIES: dict[str, tuple[str, str, str]] = {
    "offset": ("offset e", "m", "rad"),
    "damping": ("damping b", "N*s/m", "N*m*s/rad"),
    "stiffness": ("stiffness k", "N/m", "N*m/rad"),
    "zeta": ("damping ratio zeta", "1", "1"),
}
WRIST_CHANNELS = ("fx", "fy", "fz", "mx", "my", "mz")
DESIRED, ACTUAL = "desired", "actual"


def part(name: str) -> str:
    """``name`` as one entity path part."""
    return escape_entity_path_part(name)


def quantity_axis(quantity: str, axis: str) -> str:
    """The folder of one quantity on one axis: one line per run below it."""
    return f"{SERIES}/{quantity}/{part(axis)}"


def run_series(quantity: str, axis: str, run: str) -> str:
    return f"{quantity_axis(quantity, axis)}/{part(run)}"


def contact_lane(group: str, run: str) -> str:
    return f"{CONTACT}/{part(group)}/{part(run)}"


def trajectory(name: str) -> str:
    """The folder of one end trajectory (``desired``, ``actual`` or a run's name)."""
    return f"{TRAJECTORIES}/{part(name)}"


FORCE_NORM = f"{INPUT}/norm"


def limit_series(phase: str) -> str:
    """The ``transient`` or ``quasi_static`` force limit's line, beside the input."""
    return f"{INPUT}/limit_{phase}"


def input_series(axis: str) -> str:
    return f"{INPUT}/{part(axis)}"


def wrist_series(channel: str) -> str:
    return f"{WRIST}/{channel}"


def joint_series(joint: str) -> str:
    return f"{JOINTS}/{part(joint)}"


def run_trajectory(run: str) -> str:
    """The folder of one run's end trajectory (X_d + e)."""
    return f"{TRAJECTORIES}/runs/{part(run)}"
