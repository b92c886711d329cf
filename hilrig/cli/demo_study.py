"""The demo's last part: a small study recorded on the emulated rig, and its report."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console

STUDY = "study"
REPORT = "study-report.html"
#: The demo's study: 4 volunteers, each meeting both controllers once (order counterbalanced),
#: the hand's stiffness and speed drawn per volunteer.
SUBJECTS = 4
CONTROLLERS = "adaptive,fixed"
VARY = ("stiffness_n_m=200..1000", "speed_m_s=0.05..0.15")


def study_outputs(out: Path) -> list[Path]:
    """The files the study part writes that must not exist yet (its recordings are in a
    folder of their own that ``hilrig study simulate`` never writes over)."""
    return [out / STUDY / "simulation.toml", out / REPORT]


def run_study(console: Console, out: Path) -> None:
    """``hilrig study simulate`` then ``hilrig report`` into ``out``."""
    from rich.text import Text

    from hilrig.cli.report import report_command
    from hilrig.cli.study_simulate import simulate

    about = f" ({SUBJECTS} volunteers x {CONTROLLERS.replace(',', ', ')}, hand-contact)"
    console.print(Text.assemble(("study", "bold"), about))
    simulate(
        out / STUDY,
        subjects=SUBJECTS,
        controllers=CONTROLLERS,
        vary=list(VARY),
        set_=None,
    )
    report_command(out / STUDY, out / REPORT)
    console.print(
        f"catalogue: hilrig study list {out / STUDY}; report: {out / REPORT}",
        markup=False,
        highlight=False,
    )
