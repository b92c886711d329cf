"""Reading ``.rrd`` files back with Rerun's own reader (``rerun.chunk.RrdReader``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rerun.chunk import RrdReader

TIME = "time"


@dataclass(frozen=True)
class View:
    kind: str  # the class identifier: "3D", "TimeSeries", ...
    name: str
    origin: str


class Rrd:
    """The recording and the blueprint of one file, as Rerun reads them."""

    def __init__(self, path: Path) -> None:
        reader = RrdReader(path)
        self.recordings = reader.recordings()
        self.chunks = reader.stream().to_chunks()
        self.blueprint_chunks = [
            c for bp in reader.blueprints() for c in reader.stream(store=bp).to_chunks()
        ]

    def entities(self, *, static: bool | None = None) -> set[str]:
        return {c.entity_path for c in self.chunks if static is None or c.is_static == static}

    def temporal(self, entity: str, component: str) -> tuple[np.ndarray, list[Any]]:
        """Times (s) and values of ``component`` on ``entity``, in time order."""
        times: list[float] = []
        values: list[Any] = []
        for c in self.chunks:
            if c.entity_path != entity or c.is_static:
                continue
            batch = c.to_record_batch()
            if component not in batch.schema.names:
                continue
            t = batch.column(TIME).cast("int64").to_numpy() / 1e9  # duration, ns
            times.extend(t.tolist())
            values.extend(batch.column(component).to_pylist())
        order = np.argsort(times, kind="stable")
        return np.asarray(times)[order], [values[i] for i in order]

    def scalars(self, entity: str) -> tuple[np.ndarray, np.ndarray]:
        t, v = self.temporal(entity, "Scalars:scalars")
        return t, np.array([x[0] for x in v])

    def static(self, entity: str, component: str) -> Any:
        for c in self.chunks:
            if c.entity_path == entity and c.is_static:
                batch = c.to_record_batch()
                if component in batch.schema.names:
                    return batch.column(component).to_pylist()[-1]
        raise KeyError(f"{entity}: no static {component}")

    def views(self) -> list[View]:
        out = []
        for c in self.blueprint_chunks:
            batch = c.to_record_batch()
            if "ViewBlueprint:class_identifier" not in batch.schema.names:
                continue
            row = {
                n: batch.column(n).to_pylist()[-1][0]
                for n in (
                    "ViewBlueprint:class_identifier",
                    "ViewBlueprint:display_name",
                    "ViewBlueprint:space_origin",
                )
            }
            out.append(View(*row.values()))
        return out
