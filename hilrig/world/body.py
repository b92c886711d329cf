"""The human body model of ISO/TS 15066 Annex A: limits, spring constants and masses per region.

The values live in ``iso_ts_15066.toml`` beside this module (the file names its source, Table
A.2 and A.3 of ISO/TS 15066:2016); :func:`body_region` gives one region, :data:`REGIONS` all of
them, in the standard's order. Transient contact allows twice the quasi-static force and
pressure, except where the standard permits no transient contact (skull and forehead, face).

``PROBE_AREA_CM2`` is the contact area a pressure is computed for when none is given: the flat
probe of 14 mm x 14 mm with which the pain thresholds behind Table A.2 were measured (ISO/TS
15066, A.2, the Mainz study).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib.resources import files

from hilrig.errors import ParameterError

TRANSIENT_FACTOR = 2.0  # Table A.2: transient contact allows twice the quasi-static values
PROBE_AREA_CM2 = 1.4 * 1.4
SOURCE = "ISO/TS 15066:2016, Annex A, Tables A.2 and A.3"


@dataclass(frozen=True)
class BodyArea:
    """A specific body area of Table A.2 and its maximum permissible quasi-static pressure."""

    number: int
    name: str
    quasi_static_pressure_n_cm2: float


@dataclass(frozen=True)
class BodyRegion:
    """A body region: its limits (Table A.2), spring constant and effective mass (Table A.3)."""

    name: str
    label: str
    quasi_static_force_n: float
    transient_permitted: bool
    spring_constant_n_mm: float
    effective_mass_kg: float
    areas: tuple[BodyArea, ...]

    @property
    def transient_force_n(self) -> float | None:
        """The transient force limit, N (None: no transient contact is permissible)."""
        return TRANSIENT_FACTOR * self.quasi_static_force_n if self.transient_permitted else None

    @property
    def quasi_static_pressure_n_cm2(self) -> float:
        """The lowest quasi-static pressure limit of the region's areas (where in the region the
        contact was is not recorded, so the strictest applies), N/cm^2."""
        return min(area.quasi_static_pressure_n_cm2 for area in self.areas)

    @property
    def spring_constant_n_m(self) -> float:
        return 1000.0 * self.spring_constant_n_mm


def _load() -> dict[str, BodyRegion]:
    text = files("hilrig.world").joinpath("iso_ts_15066.toml").read_text(encoding="utf-8")
    regions = {}
    for name, entry in tomllib.loads(text)["regions"].items():
        regions[name] = BodyRegion(
            name,
            str(entry["label"]),
            float(entry["quasi_static_force_n"]),
            bool(entry["transient"]),
            float(entry["spring_constant_n_mm"]),
            float(entry["effective_mass_kg"]),
            tuple(
                BodyArea(int(a["number"]), str(a["name"]), float(a["quasi_static_pressure_n_cm2"]))
                for a in entry["areas"]
            ),
        )
    return regions


REGIONS: dict[str, BodyRegion] = _load()


def body_region(name: str) -> BodyRegion:
    """The region called ``name``; ParameterError (one line, listing the known) otherwise."""
    try:
        return REGIONS[name]
    except KeyError:
        known = ", ".join(REGIONS)
        raise ParameterError(f"unknown body region {name!r}; known: {known}") from None
