"""What the commands' signatures need from heavy packages, kept here so that ``hilrig --help``
loads no numeric stack: ``hilrig.control`` loads numba, ``hilrig.viz`` rerun and
``hilrig.emulator`` numpy with their packages.

Each name mirrors its source; tests/cli/test_cli_options.py pins them together.
"""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hilrig.control import Law

#: hilrig.emulator.scenarios.SCENARIOS, sorted.
SCENARIO_NAMES = ("hand-contact", "none", "paper-body", "paper-end-effector")
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
