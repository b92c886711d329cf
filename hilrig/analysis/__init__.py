"""Analysis: collision events, per-event metrics and comparison tables across controllers.

Reads recorded sessions (MCAP) and replay results (Parquet) as :class:`Source` objects, finds
collision events once per source on its force channels, measures every run on every axis of the
event's group, and compares runs against a baseline in the paper's style. The public API::

    load_sources(paths) -> tuple[Source, ...]          # files and folders
    analyze(source, events=EventConfig(...)) -> Analysis
    comparison(values([analysis]), baseline="fixed") -> DataFrame
    write_dataset(dataset_frame(analyses), root)       # partitioned Parquet dataset

Definitions of every metric: ``docs/analysis.md``.
"""

from hilrig.analysis.compare import (
    ACROSS_SOURCES,
    COMPARED,
    PER_EVENT,
    Analysis,
    analyze,
    comparison,
    default_baseline,
    metrics_frame,
    runs_of,
    values,
)
from hilrig.analysis.dataset import PARTITIONS, dataset_frame, read_dataset, write_dataset
from hilrig.analysis.events import (
    DEFAULT_EVENTS,
    AxisGroup,
    CollisionEvent,
    EventConfig,
    detect,
    detect_group,
    group_of,
    magnitude,
)
from hilrig.analysis.metrics import (
    DEFAULT_METRICS,
    UNITS,
    AxisMetrics,
    MetricsConfig,
    TrackingMetrics,
    event_metrics,
    tracking_metrics,
    unit,
)
from hilrig.analysis.report import FILE_SUFFIXES, comparison_table, events_table, write_table
from hilrig.analysis.sources import (
    Run,
    Source,
    SourceKind,
    load_replay,
    load_session,
    load_sources,
    runs_from_frame,
)
from hilrig.errors import AnalysisError

__all__ = [
    "ACROSS_SOURCES",
    "COMPARED",
    "DEFAULT_EVENTS",
    "DEFAULT_METRICS",
    "FILE_SUFFIXES",
    "PARTITIONS",
    "PER_EVENT",
    "UNITS",
    "Analysis",
    "AnalysisError",
    "AxisGroup",
    "AxisMetrics",
    "CollisionEvent",
    "EventConfig",
    "MetricsConfig",
    "Run",
    "Source",
    "SourceKind",
    "TrackingMetrics",
    "analyze",
    "comparison",
    "comparison_table",
    "dataset_frame",
    "default_baseline",
    "detect",
    "detect_group",
    "event_metrics",
    "events_table",
    "group_of",
    "load_replay",
    "load_session",
    "load_sources",
    "magnitude",
    "metrics_frame",
    "read_dataset",
    "runs_from_frame",
    "runs_of",
    "tracking_metrics",
    "unit",
    "values",
    "write_dataset",
    "write_table",
]
