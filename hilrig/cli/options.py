"""What the commands' signatures need from heavy packages, kept here so that ``hilrig --help``
loads no numeric stack: ``hilrig.control`` loads numba, ``hilrig.viz`` rerun and
``hilrig.emulator`` numpy with their packages.

Each name mirrors its source; tests/cli/test_cli_options.py pins them together.
"""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from hilrig.control import Law

#: hilrig.world.scenarios.SCENARIOS, sorted.
SCENARIO_NAMES = ("hand-contact", "none", "paper-body", "paper-end-effector")
#: hilrig.world.scenarios.settings_help(): every scenario's settings, for record --help.
SCENARIO_SETTINGS_HELP = (
    "hand-contact: direction_in_base=0,1,0 (the push's direction, base frame, x,y,z); "
    "start_s=2 (when the hand starts to move, s); gap_m=0.05 (how far short of the tool the "
    "hand waits, m); depth_m=0.03 (how far past where it meets the tool it goes, m); "
    "speed_m_s=0.1 (its approach and withdrawal speed, m/s); hold_s=1 (how long it holds at "
    "its depth, s); "
    "stiffness_n_m=300 (the hand's stiffness, N/m); damping_n_s_m=10 (the hand's damping, "
    "N*s/m); contact_point_in_sensor=0,0,0.1 (where it pushes, sensor frame, x,y,z, m); "
    "period_s=10 (repeat the collision every this many s; none: once). none: no settings. "
    "paper-body: period_s=none (repeat the collision every this many s; none: once). paper-"
    "end-effector: period_s=none (repeat the collision every this many s; none: once)."
)
#: hilrig.viz.sinks: Rerun's default gRPC and web viewer ports.
GRPC_PORT = 9876
WEB_PORT = 9090
#: hilrig.viz.log: display limits of a view.
DEFAULT_MAX_POINTS = 20_000  # per time series
DEFAULT_MAX_POSES = 5_000  # robot poses, force arrows and trajectory markers


class LawOption(StrEnum):
    """hilrig.control.Law as an option; :meth:`law` is the library's member."""

    FIXED = "fixed"
    VARIABLE_STIFFNESS = "variable-stiffness"
    ADAPTIVE = "adaptive"

    def law(self) -> Law:
        from hilrig.control import Law

        return Law(self.value)


#: The controllers, settings and sweeps of ``hilrig replay`` and ``hilrig sweep`` (one parser:
#: hilrig.replay.parse_specs).
ControllerOption = Annotated[
    list[str] | None,
    typer.Option(
        "--controller",
        "-c",
        help="A controller: LAW or NAME=LAW (adaptive, variable-stiffness, fixed). "
        "Repeat for several; default: all three laws.",
    ),
]
SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="NAME.\\[cartesian.|joint.]PARAM=VALUE, e.g. adaptive.a1=10 (repeatable).",
    ),
]
SweepOption = Annotated[
    list[str] | None,
    typer.Option(
        help="NAME.[GROUP.]PARAM=START:STOP:COUNT or =V1,V2,..; sweeps of one controller "
        "run as a grid (repeatable).",
    ),
]
