"""Files from hilrig's writer, read back by the official ``mcap`` reader and ``mcap_ros2`` decoder:
every field equals what was written, and the file carries what ROS 2 tools expect."""

from __future__ import annotations

import math
import zlib
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from recording_helpers import URDF, Written

from hilrig.recording import (
    ControllerSample,
    EventRecord,
    JointSample,
    LoopTiming,
    PoseSample,
    SessionInfo,
    WrenchSample,
    default_channels,
)
from hilrig.recording.mcap_records import Metadata
from hilrig.recording.schema import AXIS_NAMES, JOINT_NAMES

SPECS = {spec.topic: spec for spec in default_channels()}


def decoded(path: Any, topic: str) -> list[Any]:
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        return list(reader.iter_decoded_messages(topics=[topic]))


def stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def vec(v: Any) -> tuple[float, float, float]:
    return (v.x, v.y, v.z)


def same_message(topic: str, sample: Any, msg: Any) -> None:
    assert msg.header.frame_id == SPECS[topic].frame_id
    if isinstance(sample, WrenchSample):
        assert vec(msg.wrench.force) == sample.force
        assert vec(msg.wrench.torque) == sample.torque
    elif isinstance(sample, JointSample):
        assert list(msg.name) == list(JOINT_NAMES)
        assert list(msg.position) == list(sample.position)
        assert list(msg.velocity) == list(sample.velocity)
        assert list(msg.effort) == list(sample.effort)
    elif isinstance(sample, PoseSample):
        assert vec(msg.pose.position) == sample.position
        o = msg.pose.orientation
        assert (o.x, o.y, o.z, o.w) == sample.orientation
    elif isinstance(sample, ControllerSample):
        assert msg.controller == "adaptive"
        assert list(msg.axis_names) == list(AXIS_NAMES)
        for field in ("force", "offset", "offset_rate", "damping", "stiffness", "chi", "zeta"):
            assert list(getattr(msg, field)) == list(getattr(sample, field)), field
        assert list(msg.contact_state) == list(sample.contact_state)
    elif isinstance(sample, LoopTiming):
        for field in ("tick", "period_ns", "compute_ns", "lateness_ns", "overruns", "queue_drops"):
            assert getattr(msg, field) == getattr(sample, field), field
    else:
        assert isinstance(sample, EventRecord)
        assert (msg.kind, msg.source, msg.detail, msg.axis) == (
            int(sample.kind),
            sample.source,
            sample.detail,
            sample.axis,
        )
        assert msg.value == sample.value or (math.isnan(msg.value) and math.isnan(sample.value))


@pytest.mark.parametrize("topic", sorted(SPECS))
def test_every_field_decodes_as_written(small_session: Written, topic: str) -> None:
    written = small_session.of(topic)
    found = decoded(small_session.path, topic)
    assert len(found) == len(written) > 0
    for counter, (sample, item) in enumerate(zip(written, found, strict=True)):
        log_ns = small_session.log_ns(sample)
        assert item.message.log_time == log_ns
        assert stamp_ns(item.decoded_message) == log_ns
        if topic == "/joint_states":  # the robot stamps its samples: device time and sequence
            assert isinstance(sample, JointSample)
            assert item.message.publish_time == sample.device_t_ns
            assert item.message.sequence == sample.device_seq
        else:
            assert item.message.publish_time == log_ns
            assert item.message.sequence == counter
        same_message(topic, sample, item.decoded_message)


def test_file_follows_the_ros2_profile(small_session: Written) -> None:
    with open(small_session.path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(small_session.samples)
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == "cdr"
        assert schema.encoding == "ros2msg"
        assert "history: 1" in channel.metadata["offered_qos_profiles"]
        text = schema.data.decode()
        if schema.name != "std_msgs/msg/String":  # every stamped type carries its dependencies
            assert "MSG: builtin_interfaces/Time\n" in text  # Rerun needs it for the header
            assert "MSG: std_msgs/Header\n" in text
    names = {schema.name for schema in summary.schemas.values()}
    assert "geometry_msgs/msg/WrenchStamped" in names
    assert "hilrig_msgs/msg/ControllerState" in names
    assert all(len(index.message_index_offsets) > 0 for index in summary.chunk_indexes)


def test_session_calibration_and_attachments_are_stored(small_session: Written) -> None:
    with open(small_session.path, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
    assert SessionInfo.from_metadata(metadata["session"]) == small_session.info
    assert metadata["session"]["start_utc"] == "2026-01-01T00:00:00.000000000Z"
    calibration = {"ft_wrist.bias_N": "[0.1, -0.2, 0.05]", "tool_mass_kg": "0.8"}
    record = Metadata("calibration", calibration).encode()  # sealed with its CRC (format doc)
    assert metadata["calibration"] == {**calibration, "hilrig.crc32": f"{zlib.crc32(record):08x}"}
    assert metadata["rosbag2"] == {"serialized_metadata": ""}
    assert attachments["robot.urdf"].data == URDF.encode()
    assert attachments["robot.urdf"].media_type == "application/xml"
    assert attachments["config.toml"].data == b"rate_hz = 1000\n"


def test_the_urdf_is_published_latched_on_robot_description(small_session: Written) -> None:
    (item,) = decoded(small_session.path, "/robot_description")
    assert item.decoded_message.data == URDF
    assert item.schema.name == "std_msgs/msg/String"
    assert item.message.log_time == small_session.info.start_utc_ns
    qos = item.channel.metadata["offered_qos_profiles"]
    assert "durability: 1\n" in qos and "depth: 1\n" in qos  # transient local, like ROS


def test_every_chunk_spans_less_than_the_crash_bound(small_session: Written) -> None:
    with open(small_session.path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert len(summary.chunk_indexes) >= 4
    for index in summary.chunk_indexes:
        assert index.compression == "zstd"
        assert index.message_end_time - index.message_start_time < 250_000_000
