"""The result contract: one table, one row per (controller run, tick).

Columns, in order: ``run`` (the run's name) and ``law`` (both categorical strings), ``t_s``
(float64, the tick's start from the start of the input, s), then for each axis of the input
(``x y z joint1 .. joint6``, those present) ``force_<axis>`` (N or N*m), ``offset_<axis>`` (e,
m or rad, commanded at the tick: e(t + dt)), ``velocity_<axis>`` (e', m/s or rad/s),
``damping_<axis>`` (b held over the tick), ``stiffness_<axis>`` (k), ``zeta_<axis>`` (damping
ratio b/(2 sqrt(m k))), all float64, and ``contact_<axis>`` (int8 ContactState code of the
axis's group: 0 free, 1 contact, 2 holding, 3 recovering). Rows are grouped by run, in the
order the runs were given, ticks ascending.

In a result file the six per-axis quantities are float32 by default (:func:`stored_float32`):
each value is the float64 one rounded to nearest, off by at most :func:`float32_error` of it
(2**-24 relative); ``t_s`` stays float64 (in float32 an hour's times would be 0.24 ms apart,
a quarter of a 1 kHz tick, and the recorded ticks' jitter would be lost), ``contact_<axis>``
int8. A column with a value beyond float32's range (3.4e38) is kept float64.

The parameters of every run are ``table.attrs["hilrig.runs"]`` (and the Parquet schema
metadata key ``hilrig.runs``): JSON ``{run name: {"law", "controller", "settings", "dt_s",
"axes", "params"}}``, ``params`` being every AdmittanceParams field for the input's axes
(per-axis values as lists in axis order). ``hilrig.input`` describes the input.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from hilrig.control import OUTPUTS, AdmittanceParams, Law
from hilrig.replay.blocks import Blocks
from hilrig.replay.specs import ControllerSpec, Value
from hilrig.replay.trace import ForceTrace

RUNS_KEY = "hilrig.runs"
INPUT_KEY = "hilrig.input"
QUANTITIES = ("force", "offset", "velocity", "damping", "stiffness", "zeta")
CONTACT = "contact"
#: Rows of the float block: the controller's outputs in the order it writes them, then force
#: and zeta (filled afterwards).
FLOAT_ROWS = {quantity: row for row, quantity in enumerate((*OUTPUTS, "force", "zeta"))}
_BYTES_PER_AXIS_ROW = len(FLOAT_ROWS) * 8 + 1
#: Rounding a float64 to float32 (to nearest) errs by at most this fraction of the value
#: (the unit roundoff)...
FLOAT32_RELATIVE_ERROR = 2.0**-24
#: ... or, below float32's normal range (2**-126), by at most this much (half the subnormal
#: spacing; smaller values round to 0).
FLOAT32_ABSOLUTE_ERROR = 2.0**-150


@dataclass(frozen=True)
class Run:
    """One controller run: ``params`` are for exactly the input's axes (combined groups)."""

    name: str
    law: Law
    params: AdmittanceParams
    controller: str = ""
    settings: Mapping[str, Value] = field(default_factory=dict)

    @classmethod
    def from_spec(cls, spec: ControllerSpec, axis_names: Sequence[str]) -> Run:
        """The run of ``spec`` on an input with ``axis_names``; raises ReplayError."""
        return cls(
            spec.name, spec.law, spec.params_for(axis_names), spec.controller, spec.overrides
        )

    def metadata(self, trace: ForceTrace) -> dict[str, Any]:
        """The run's entry of ``hilrig.runs`` (JSON-ready)."""
        settings = {k: list(v) if isinstance(v, tuple) else v for k, v in self.settings.items()}
        return {
            "law": self.law.value,
            "controller": self.controller or self.name,
            "settings": settings,
            "dt_s": trace.dt_s,
            "axes": list(trace.axis_names),
            "params": _plain(asdict(self.params)),
        }


def _plain(value: Any) -> Any:
    """Tuples as lists, enums as their values: what json.dumps writes and reads back."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, str):
        return str(value)
    return value


def input_metadata(trace: ForceTrace) -> dict[str, Any]:
    """``hilrig.input``: where the trace came from and its sampling."""
    session = trace.session
    return {
        "source": trace.source,
        "ticks": trace.ticks,
        "dt_s": trace.dt_s,
        "axes": list(trace.axis_names),
        "t0_ns": trace.t0_ns,
        "session_id": None if session is None else session.session_id,
        "subject_id": None if session is None else session.subject_id,
        "body_region": None if session is None else session.body_region or None,
        "contact_area_cm2": None if session is None else session.contact_area_cm2,
        "notes": list(trace.notes),
    }


def column_names(axis_names: Sequence[str]) -> list[str]:
    """The table's columns for an input with ``axis_names``, in contract order."""
    names = ["run", "law", "t_s"]
    for axis in axis_names:
        names += [f"{q}_{axis}" for q in QUANTITIES] + [f"{CONTACT}_{axis}"]
    return names


def stored_float32(name: str) -> bool:
    """Whether column ``name`` is one of the per-axis quantities a result file may store as
    float32 (``force_x`` .. ``zeta_joint6``; not ``t_s``)."""
    quantity, _, axis = name.partition("_")
    return quantity in QUANTITIES and bool(axis)


def float32_error(value: float) -> float:
    """The largest |x - float32(x)| for |x| <= ``value`` (in x's unit), within float32's range."""
    return max(FLOAT32_RELATIVE_ERROR * abs(value), FLOAT32_ABSOLUTE_ERROR)


def table_bytes(axes: int, rows: int) -> int:
    """Memory of a result table of ``rows`` rows (all runs) over ``axes`` axes."""
    return rows * (axes * _BYTES_PER_AXIS_ROW + 8 + 2)


def frame(trace: ForceTrace, runs: Sequence[Run], blocks: Blocks) -> pd.DataFrame:
    """The contract table over ``blocks`` (no copy of the per-axis columns)."""
    ticks = trace.ticks
    codes = np.repeat(np.arange(len(runs), dtype=_code_type(len(runs))), ticks)
    laws = list(dict.fromkeys(r.law.value for r in runs))
    law_codes = np.array([laws.index(r.law.value) for r in runs], dtype=np.int8)
    columns: dict[str, Any] = {
        "run": pd.Categorical.from_codes(codes, categories=pd.Index([r.name for r in runs])),
        "law": pd.Categorical.from_codes(np.repeat(law_codes, ticks), categories=pd.Index(laws)),
        "t_s": np.tile(trace.t_s, len(runs)),
    }
    for i, axis in enumerate(trace.axis_names):
        for quantity in QUANTITIES:
            columns[f"{quantity}_{axis}"] = blocks.floats[i, FLOAT_ROWS[quantity]]
        columns[f"{CONTACT}_{axis}"] = blocks.contact[i]
    table = pd.DataFrame(columns, copy=False)
    table.attrs[RUNS_KEY] = {r.name: r.metadata(trace) for r in runs}
    table.attrs[INPUT_KEY] = input_metadata(trace)
    return table


def _code_type(count: int) -> type[np.signedinteger[Any]]:
    if count < 2**7:
        return np.int8
    return np.int16 if count < 2**15 else np.int32


def run_slices(table: pd.DataFrame) -> dict[str, slice]:
    """``{run name: its rows}`` of a contract table (rows are grouped by run)."""
    run = table["run"]
    codes = np.asarray(run.cat.codes)
    if len(codes) == 0:
        return {}
    starts = np.concatenate([[0], np.flatnonzero(np.diff(codes)) + 1])
    ends = np.concatenate([starts[1:], [len(codes)]])
    names = run.cat.categories
    return {str(names[codes[s]]): slice(int(s), int(e)) for s, e in zip(starts, ends, strict=True)}


def peak_offsets(table: pd.DataFrame, axis_names: Sequence[str]) -> dict[str, dict[str, float]]:
    """``{run: {axis: max |offset|}}`` (m or rad) of a contract table."""
    peaks: dict[str, dict[str, float]] = {}
    for name, rows in run_slices(table).items():
        peaks[name] = {
            axis: float(np.abs(table[f"offset_{axis}"].to_numpy()[rows]).max())
            for axis in axis_names
        }
    return peaks
