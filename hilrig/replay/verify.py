"""Determinism check: replay a recording through the controller it was recorded with.

The live loop steps the same compiled kernel as the replay on every tick, so the replayed state
must equal the recorded ``/controller/state`` - offset, offset rate, damping, stiffness, zeta
to within ``tolerance`` (default 1e-12, in the quantity's unit) and contact states exactly.

The controller is the one the session record names: its ``controller_params`` carry the law,
``rate_hz`` and every AdmittanceParams field of the combined 9-axis controller (values as
their Python ``str()``, which round-trips floats exactly, or as plain JSON values). A recording
without those fields is checked against the live loop's defaults (law ``adaptive``, presets
``adaptive`` and ``adaptive-joint``), and the report says so.
"""

from __future__ import annotations

import ast
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from hilrig.control import AdmittanceParams, Law, ParameterError
from hilrig.errors import RecordingError, ReplayError
from hilrig.recording import read
from hilrig.replay.engine import Progress, replay
from hilrig.replay.inputs import (
    STATE_TOPIC,
    PathLike,
    SessionIndex,
    session_index,
    trace_from_state,
)
from hilrig.replay.results import Run
from hilrig.replay.specs import parse_specs

TOLERANCE = 1e-12
#: Recorded ``/controller/state`` array -> result-table quantity.
COMPARED = {
    "offset": "offset",
    "offset_rate": "velocity",
    "damping": "damping",
    "stiffness": "stiffness",
    "zeta": "zeta",
    "contact_state": "contact",
}
_FIELDS = tuple(f.name for f in fields(AdmittanceParams))


@dataclass(frozen=True)
class Difference:
    """The largest difference of one recorded quantity: where it is and both values."""

    quantity: str
    axis: str
    tick: int
    t_s: float
    recorded: float
    replayed: float

    @property
    def size(self) -> float:
        return abs(self.replayed - self.recorded)

    def describe(self) -> str:
        return (
            f"{self.quantity} of {self.axis} at tick {self.tick} (t = {self.t_s:.6f} s): "
            f"recorded {self.recorded!r}, replayed {self.replayed!r}"
        )


@dataclass(frozen=True)
class VerifyReport:
    """What ``--verify`` found: the controller used, and the largest difference of each
    compared quantity (None when the recording has no ticks of it)."""

    path: Path
    law: Law
    dt_s: float
    ticks: int
    axes: tuple[str, ...]
    params_source: str
    largest: tuple[Difference, ...]
    tolerance: float = TOLERANCE

    @property
    def worst(self) -> Difference:
        return max(self.largest, key=lambda d: d.size)

    @property
    def ok(self) -> bool:
        """Every float within ``tolerance`` and every contact state equal."""
        return all(
            d.size == 0 if d.quantity == "contact_state" else d.size <= self.tolerance
            for d in self.largest
        )


def verify(
    path: PathLike, *, tolerance: float = TOLERANCE, progress: Progress | None = None
) -> VerifyReport:
    """Replay ``path``'s ``/controller/state`` input through its recorded controller and compare
    with the recorded state. Raises ReplayError (one line) if there is nothing to verify."""
    p = Path(path)
    index = session_index(p)
    if STATE_TOPIC not in index.topics:
        raise ReplayError(f"{p}: no {STATE_TOPIC}: nothing recorded to verify against")
    try:
        load = None if progress is None else (lambda d, t: progress("load", d, t))
        state = read(p, [STATE_TOPIC], progress=load).frames[STATE_TOPIC]
    except RecordingError as err:
        raise ReplayError(str(err)) from err
    trace = trace_from_state(p, state, index)
    law, params, source = recorded_controller(p, index, trace.axis_names)
    table = replay(trace, [Run("recorded", law, params)], jobs=1, progress=progress)
    largest = []
    for recorded_name, quantity in COMPARED.items():
        recorded = np.stack(
            [state[f"{recorded_name}_{i}"].to_numpy() for i in range(len(trace.axis_names))], 1
        ).astype(np.float64)
        replayed = np.stack(
            [table[f"{quantity}_{a}"].to_numpy() for a in trace.axis_names], 1
        ).astype(np.float64)
        gap = np.abs(replayed - recorded)
        gap[np.isnan(gap)] = np.inf  # NaN on one side only is a difference
        tick, axis = np.unravel_index(int(np.argmax(gap)), gap.shape)
        largest.append(
            Difference(
                recorded_name,
                trace.axis_names[axis],
                int(tick),
                float(trace.t_s[tick]),
                float(recorded[tick, axis]),
                float(replayed[tick, axis]),
            )
        )
    return VerifyReport(
        p, law, trace.dt_s, trace.ticks, trace.axis_names, source, tuple(largest), tolerance
    )


def recorded_controller(
    path: Path, index: SessionIndex, axis_names: Sequence[str]
) -> tuple[Law, AdmittanceParams, str]:
    """The law and parameters (for ``axis_names``) a recording was made with, and where they
    came from. Raises ReplayError if the recorded ones are unusable."""
    raw = index.controller_params
    law_name = str(raw.get("law") or (index.session.controller if index.session else ""))
    values = {name: _plain(raw[name]) for name in _FIELDS if name in raw}
    try:
        law = Law(law_name or Law.ADAPTIVE.value)
        if not values:
            params = parse_specs([law.value])[0].params_for(axis_names)
            return law, params, "the live loop's defaults (the recording lists no parameters)"
        return law, AdmittanceParams(**values), "the recording's session metadata"
    except (ParameterError, TypeError, ValueError) as err:
        raise ReplayError(f"{path}: recorded controller: {err}") from err


def _plain(value: Any) -> Any:
    """A recorded parameter value: ``str()`` of a Python value read back, or JSON as is."""
    if not isinstance(value, str):
        return value
    try:
        return ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return value  # a name: "cap", "square", "zoh"


def summary_lines(report: VerifyReport) -> list[str]:
    """The report for people: the controller, then each quantity's largest difference."""
    lines = [
        f"{report.path}: {report.ticks} ticks at {1 / report.dt_s:g} Hz through {report.law.value} "
        f"({', '.join(report.axes)}), parameters from {report.params_source}",
    ]
    for d in report.largest:
        lines.append(f"  {d.quantity:<14} largest difference {d.size:.3g}")
    worst = report.worst
    line = f"largest difference {worst.size:.3g} (tolerance {report.tolerance:g})"
    lines.append(f"OK: {line}" if report.ok else f"FAILED: {line} in {worst.describe()}")
    return lines
