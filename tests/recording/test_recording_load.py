"""``hilrig.recording.load``: columns equal to what was written and to the generic decoder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader
from mcap_ros2.writer import Writer as Ros2Writer
from recording_helpers import Written, write_session

from hilrig.errors import RecordingError
from hilrig.recording import (
    ControllerSample,
    JointSample,
    SplitPolicy,
    WrenchSample,
    load,
    read,
)
from hilrig.recording.generic import decode_frame
from hilrig.recording.mcap_records import Schema
from hilrig.recording.msgdef import full_definition
from hilrig.recording.schema import AXIS_NAMES, JOINT_NAMES


def test_wrench_columns_equal_the_samples(small_session: Written) -> None:
    frame = load(small_session.path, topics=["/ft/base"])["/ft/base"]
    samples = small_session.of("/ft/base")
    assert all(isinstance(s, WrenchSample) for s in samples)
    expected_log = [small_session.log_ns(s) for s in samples]
    assert frame.index.name == "log_time_ns"
    assert frame.index.dtype == np.int64
    assert frame.index.tolist() == expected_log
    assert frame["header.stamp_ns"].tolist() == expected_log
    assert frame["publish_time_ns"].tolist() == expected_log
    assert frame["sequence"].tolist() == list(range(len(samples)))
    assert set(frame["header.frame_id"]) == {"ft_base"}
    forces = np.array([s.force for s in samples if isinstance(s, WrenchSample)])
    assert np.array_equal(frame[["wrench.force.x", "wrench.force.y", "wrench.force.z"]], forces)
    assert frame["wrench.force.x"].to_numpy().flags.c_contiguous


def test_joint_and_controller_arrays_become_numbered_columns(small_session: Written) -> None:
    frames = load(small_session.path, topics=["/joint_states", "/controller/state"])
    joints = frames["/joint_states"]
    written = [s for s in small_session.of("/joint_states") if isinstance(s, JointSample)]
    assert [joints[f"name_{i}"].iloc[0] for i in range(6)] == list(JOINT_NAMES)
    assert np.array_equal(joints[[f"effort_{i}" for i in range(6)]], [s.effort for s in written])
    assert joints["publish_time_ns"].tolist() == [s.device_t_ns for s in written]
    assert joints["sequence"].tolist() == [s.device_seq for s in written]
    state = frames["/controller/state"]
    ticks = [s for s in small_session.of("/controller/state") if isinstance(s, ControllerSample)]
    assert state["controller"].iloc[-1] == "adaptive"
    assert [state[f"axis_names_{i}"].iloc[0] for i in range(9)] == list(AXIS_NAMES)
    assert np.array_equal(state[[f"zeta_{i}" for i in range(9)]], [s.zeta for s in ticks])
    contact = state[[f"contact_state_{i}" for i in range(9)]]
    assert (contact.dtypes == np.int8).all()
    assert np.array_equal(contact, [s.contact_state for s in ticks])


def test_fast_path_equals_the_generic_decoder(small_session: Written) -> None:
    frames = load(small_session.path)
    with open(small_session.path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        for channel in summary.channels.values():
            s = summary.schemas[channel.schema_id]
            raw = [
                (m.log_time, m.publish_time, m.sequence, m.data)
                for _, _, m in reader.iter_messages(topics=[channel.topic])
            ]
            generic = decode_frame(Schema(s.id, s.name, s.encoding, s.data), raw)
            pd.testing.assert_frame_equal(frames[channel.topic], generic, check_categorical=False)


def test_time_range_and_topics_select_like_the_mcap_reader(small_session: Written) -> None:
    first = small_session.log_ns(small_session.samples[0][1])
    start, end = first + 333_000_000, first + 777_000_000
    topics = ["/ft/wrist", "/events", "/diagnostics/loop"]
    frames = load(small_session.path, topics=topics, start_ns=start, end_ns=end)
    assert sorted(frames) == sorted(topics)
    with open(small_session.path, "rb") as f:
        reader = make_reader(f)
        for topic in topics:
            times = [
                m.log_time
                for _, _, m in reader.iter_messages(
                    topics=[topic], starting_at=start, ending_before=end
                )
            ]
            assert frames[topic].index.tolist() == times


def test_one_topic_may_be_given_as_a_string(small_session: Written) -> None:
    assert list(load(small_session.path, topics="/ft/wrist")) == ["/ft/wrist"]


def test_unknown_topic_is_a_one_line_error(small_session: Written) -> None:
    with pytest.raises(RecordingError, match=r"small\.mcap: no topic /nope \(has /controller"):
        load(small_session.path, topics=["/nope"])


def test_split_session_parts_are_each_valid_and_load_together(tmp_path: Path) -> None:
    written = write_session(tmp_path / "long.mcap", 1600, split=SplitPolicy(max_duration_s=0.5))
    parts = sorted(tmp_path.glob("long_*.mcap"))
    assert [p.name for p in parts] == ["long_000.mcap", "long_001.mcap", "long_002.mcap"]
    total = 0
    for part in parts:
        with open(part, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            total += sum(1 for _ in reader.iter_messages())
            session = {m.name: m.metadata for m in reader.iter_metadata()}["session"]
            assert session["session_id"] == written.info.session_id
            assert session["part"] == str(parts.index(part))
            robot = list(reader.iter_messages(topics=["/robot_description"]))
            assert len(robot) == 1  # every part stands alone in a viewer
    assert total == len(written.samples) + len(parts) - 1
    frames = load(parts)
    assert len(frames["/ft/wrist"]) == 1600
    assert frames["/ft/wrist"].index.is_monotonic_increasing


def test_foreign_file_with_variable_messages_takes_the_generic_path(tmp_path: Path) -> None:
    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as f:
        writer = Ros2Writer(f)
        schema = writer.register_msgdef(
            "sensor_msgs/msg/JointState", full_definition("sensor_msgs/msg/JointState")
        )
        for i in range(50):
            names = [f"j{k}" for k in range(1 + i % 3)]  # the joint count changes
            message = {
                "header": {"stamp": {"sec": 10, "nanosec": i}, "frame_id": "base"},
                "name": names,
                "position": [0.5 * i] * len(names),
            }
            writer.write_message("/joints", schema, message, log_time=1000 + i, publish_time=i)
        writer.finish()
    frame = read(path).frames["/joints"]
    assert len(frame) == 50
    assert frame["position_0"].tolist() == [0.5 * i for i in range(50)]
    assert frame["position_2"].isna().sum() == 50 - 16
    assert frame["header.stamp_ns"].iloc[3] == 10_000_000_003
