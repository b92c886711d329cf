"""Representative events: per condition and axis group, the event whose peak force is the
condition's median, with its force, offset and the controller's b, k and zeta over time.

The median event (the one closest to the median peak force of the condition's included events,
the earlier on a tie) stands for the condition: a typical collision, not the worst one.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from hilrig.errors import HilrigError
from hilrig.recording import load
from hilrig.study.records import EventCurve

STATE_TOPIC = "/controller/state"
BEFORE_S = 0.2  # shown before the event's start
AFTER_S = 2.0  # shown after the force is gone: the recovery
FIELDS = ("force", "offset", "damping", "stiffness", "zeta")


def representatives(observations: pd.DataFrame) -> pd.DataFrame:
    """Per (group, condition) the observation row (metric peak_force) of its median event."""
    peaks = observations[observations["metric"] == "peak_force"].dropna(subset=["value"])
    rows = []
    for _, rows_of in peaks.groupby(["group", "condition"], sort=False):
        distance = (rows_of["value"] - rows_of["value"].median()).abs().to_numpy()
        rows.append(rows_of.iloc[int(np.argmin(distance))])
    return pd.DataFrame(rows).reset_index(drop=True)


def curves(
    chosen: pd.DataFrame, tables: Mapping[str, pd.DataFrame], files: Mapping[str, list[Path]]
) -> tuple[EventCurve, ...]:
    """The chosen events' curves, read from their sessions' ``/controller/state`` (an event
    whose session cannot be read again is left out)."""
    found = []
    for _, row in chosen.iterrows():
        table = tables[str(row["session"])]
        event = table[table["event"] == row["event"]].iloc[0]
        curve = _curve(files[str(row["session"])], event, row)
        if curve is not None:
            found.append(curve)
    return tuple(found)


def _curve(paths: list[Path], event: pd.Series, row: pd.Series) -> EventCurve | None:
    t0 = int(event["t0_ns"])
    start_ns = t0 + int((float(event["start_s"]) - BEFORE_S) * 1e9)
    end_ns = t0 + int((float(event["end_s"]) + AFTER_S) * 1e9)
    try:
        state = load(paths if len(paths) > 1 else paths[0], [STATE_TOPIC], start_ns, end_ns)
    except HilrigError:
        return None
    frame = state.get(STATE_TOPIC)
    if frame is None or frame.empty:
        return None
    names = [str(frame[c].iloc[0]) for c in frame.columns if c.startswith("axis_names_")]
    axis = str(event["axis"])
    if axis not in names:
        return None
    i = names.index(axis)
    t_s = (frame.index.to_numpy(dtype=np.int64) - t0) / 1e9 - float(event["start_s"])
    values = {name: frame[f"{name}_{i}"].to_numpy(dtype=np.float64) for name in FIELDS}
    return EventCurve(
        condition=str(row["condition"]),
        subject=str(row["subject"]),
        session=str(row["session"]),
        event=int(event["event"]),
        group=str(event["group"]),
        axis=axis,
        t_s=t_s,
        **values,
    )
