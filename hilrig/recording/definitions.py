"""hilrig's own schemas and channels, checked: in a file hilrig wrote, their text is known.

Schema and Channel records carry no CRC, so a changed byte in them is found only by
comparison: with the summary's copies (:mod:`.scan`) or, in a file whose header says hilrig
wrote it, with what hilrig writes - the packaged definition of each of its message types
(format ``hilrig-recording/1`` fixes them), and the channel metadata a
:class:`~.schema.ChannelSpec` gives. A record that differs is damaged and left out, and so
are the messages of a channel whose record is.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from hilrig.recording.mcap_records import SEAL_KEY, Op, Schema
from hilrig.recording.msgdef import full_definition
from hilrig.recording.schema import (
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    TOPICS,
    ChannelSpec,
    MessageType,
)
from hilrig.recording.session import FORMAT_VERSION, SESSION_METADATA

if TYPE_CHECKING:
    from hilrig.recording.file_index import FileIndex
    from hilrig.recording.mcap_records import Channel

_ROS_NAME = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")
_TYPES = {t.value: t for t in MessageType}
#: Every channel metadata hilrig writes: latched or not, device clock or not.
_CHANNEL_METADATA = [
    ChannelSpec("/t", MessageType.STRING, latched=latched, device_clock=device).metadata
    for latched in (False, True)
    for device in (False, True)
]


#: The ``rosbag2`` metadata record hilrig writes (docs/recording-format.md).
ROSBAG2_METADATA = {"serialized_metadata": ""}


def written_by_hilrig(index: FileIndex) -> bool:
    """The header names hilrig as the writer, or the session record names its format."""
    session = index.values.get(SESSION_METADATA, {})
    return index.library.startswith("hilrig/") or session.get("format") == FORMAT_VERSION


def check_definitions(index: FileIndex) -> None:
    """In a file hilrig wrote, drop (as damaged) schemas, channels and the ``rosbag2``
    metadata record when hilrig would not write them so."""
    if not written_by_hilrig(index):
        return
    rosbag2 = index.values.get("rosbag2", ROSBAG2_METADATA)
    if rosbag2 != ROSBAG2_METADATA:
        index.drop_metadata("rosbag2", "it is not what hilrig writes")
    for schema_id, schema in list(index.schemas.items()):
        kind = _TYPES.get(schema.name)
        if kind is None:
            problem = f"unknown type name {schema.name!r}"
        elif schema.encoding != SCHEMA_ENCODING:
            problem = f"encoding {schema.encoding!r} is not {SCHEMA_ENCODING!r}"
        elif schema.data != full_definition(kind.value).encode():
            problem = f"its definition of {schema.name} differs from the one hilrig writes"
        else:
            continue
        del index.schemas[schema_id]
        offset = index.definition_offsets.get((Op.SCHEMA, schema_id), 0)
        index.damaged(f"schema record {schema_id}", offset, problem)
    for channel_id, channel in list(index.channels.items()):
        problem = _channel_problem(index, channel)
        if problem:
            del index.channels[channel_id]
            offset = index.definition_offsets.get((Op.CHANNEL, channel_id), 0)
            index.damaged(f"channel record {channel_id}", offset, problem)
    _restore_schemas(index)


def _restore_schemas(index: FileIndex) -> None:
    """Write anew the schemas of hilrig's topics that are missing or were damaged: in a file
    hilrig wrote, the topic gives the type, and the format fixes its definition."""
    wanted: dict[int, set[MessageType]] = {}
    for channel in index.channels.values():
        kind = TOPICS.get(channel.topic)
        if kind is not None and channel.schema_id and channel.schema_id not in index.schemas:
            wanted.setdefault(channel.schema_id, set()).add(kind)
    for schema_id, kinds in wanted.items():
        if len(kinds) == 1:
            (kind,) = kinds
            text = full_definition(kind.value).encode()
            index.schemas[schema_id] = Schema(schema_id, kind.value, SCHEMA_ENCODING, text)
            offset = index.definition_offsets.get((Op.SCHEMA, schema_id), 0)
            detail = f"missing or damaged; written anew as hilrig's {kind.value}"
            index.damaged(f"schema record {schema_id}", offset, detail)


def drop_schemaless(index: FileIndex) -> None:
    """Channels whose schema is missing are damage: left out, and their messages with them."""
    for channel_id, channel in list(index.channels.items()):
        if channel.schema_id and channel.schema_id not in index.schemas:
            del index.channels[channel_id]
            offset = index.definition_offsets.get((Op.CHANNEL, channel_id), 0)
            detail = f"topic {channel.topic}: its schema {channel.schema_id} is missing"
            index.damaged(f"channel record {channel_id}", offset, detail)


def _channel_problem(index: FileIndex, channel: Channel) -> str:
    schema = index.schemas.get(channel.schema_id)
    known = TOPICS.get(channel.topic)
    if not _ROS_NAME.fullmatch(channel.topic):
        return f"topic {channel.topic!r} is not a ROS name"
    if channel.message_encoding != MESSAGE_ENCODING:
        return f"topic {channel.topic}: encoding {channel.message_encoding!r} is not cdr"
    if schema is not None and known is not None and schema.name != known.value:
        return f"topic {channel.topic}: type {schema.name} is not {known.value}"
    if {k: v for k, v in channel.metadata.items() if k != SEAL_KEY} not in _CHANNEL_METADATA:
        return f"topic {channel.topic}: its metadata is not what hilrig writes"
    return ""
