"""Colours and labels: one colour per controller run in every view, fixed colours for the rest.

Runs take the Okabe-Ito colour-blind-safe palette in the order they are shown (the recorded
controller first), then repeat it. Cartesian axes are red, green, blue (x, y, z) as in every 3D
tool; joints have their own six colours.
"""

from __future__ import annotations

from collections.abc import Sequence

from hilrig.recording.samples import ContactState

RGB = tuple[int, int, int]

RUN_PALETTE: tuple[RGB, ...] = (
    (230, 159, 0),  # orange
    (86, 180, 233),  # sky blue
    (0, 158, 115),  # bluish green
    (204, 121, 167),  # reddish purple
    (240, 228, 66),  # yellow
    (0, 114, 178),  # blue
    (213, 94, 0),  # vermillion
)
DESIRED: RGB = (150, 150, 150)
ACTUAL: RGB = (235, 235, 235)
ROBOT: RGB = (200, 200, 210)
FORCE: RGB = (255, 64, 64)
FORCE_NORM: RGB = (255, 255, 255)  # |F| beside the ISO/TS 15066 limits
LIMITS: dict[str, RGB] = {"transient": (255, 140, 0), "quasi_static": (220, 30, 30)}
AXIS_COLORS: dict[str, RGB] = {
    "x": (230, 60, 60),
    "y": (60, 190, 60),
    "z": (70, 110, 240),
    "joint1": (230, 159, 0),
    "joint2": (86, 180, 233),
    "joint3": (0, 158, 115),
    "joint4": (204, 121, 167),
    "joint5": (240, 228, 66),
    "joint6": (213, 94, 0),
}
CONTACT_COLORS: dict[ContactState, RGB] = {
    ContactState.FREE: (80, 80, 80),
    ContactState.CONTACT: (220, 50, 50),
    ContactState.HOLDING: (240, 180, 40),
    ContactState.RECOVERING: (60, 160, 230),
}


def run_colors(names: Sequence[str]) -> dict[str, RGB]:
    """``{run name: colour}`` in the order given, the palette repeating after seven runs."""
    return {name: RUN_PALETTE[i % len(RUN_PALETTE)] for i, name in enumerate(names)}


def hex_color(rgb: RGB) -> str:
    """``#rrggbb`` of ``rgb``."""
    return "#{:02x}{:02x}{:02x}".format(*rgb)
