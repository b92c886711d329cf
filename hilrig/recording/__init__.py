"""Recording: hilrig sessions as MCAP files that Rerun, Foxglove, PlotJuggler and rosbag2 open.

Write with :class:`SessionWriter` (typed samples, one ``struct`` call per message, crash-safe
chunks), read with :func:`load` (one pandas frame per topic), repair with :func:`recover`,
describe with :func:`inspect`, convert with :func:`export`. The file format is documented in
``docs/recording-format.md``.
"""

from hilrig.recording.export import export
from hilrig.recording.info import FileInfo, TopicInfo, inspect
from hilrig.recording.mcap_records import Attachment
from hilrig.recording.outcome import SessionOutcome
from hilrig.recording.reader import Loaded, RecordingWarning, load, read
from hilrig.recording.recover import Recovery, recover
from hilrig.recording.samples import (
    ContactState,
    ControllerSample,
    EventKind,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    Sample,
    TextSample,
    WrenchSample,
)
from hilrig.recording.schema import TOPICS, ChannelSpec, MessageType, default_channels
from hilrig.recording.session import SessionInfo, validate_subject_id
from hilrig.recording.split import SplitPolicy, part_path
from hilrig.recording.writer import SessionWriter

__all__ = [
    "TOPICS",
    "Attachment",
    "ChannelSpec",
    "ContactState",
    "ControllerSample",
    "EventKind",
    "EventRecord",
    "FileInfo",
    "JointSample",
    "Loaded",
    "LoopTiming",
    "MessageType",
    "PoseSample",
    "RecordingWarning",
    "Recovery",
    "Sample",
    "SessionInfo",
    "SessionOutcome",
    "SessionWriter",
    "SplitPolicy",
    "TextSample",
    "TopicInfo",
    "WrenchSample",
    "default_channels",
    "export",
    "inspect",
    "load",
    "part_path",
    "read",
    "recover",
    "validate_subject_id",
]
