"""``rerun mcap convert`` (the CLI shipped with rerun-sdk) decodes every hilrig topic - standard
types into Rerun's own archetypes or structs, hilrig's messages by reflection - never raw bytes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from recording_helpers import Written
from rerun.chunk import RrdReader

from hilrig.recording import WrenchSample

RERUN = str(Path(sys.executable).parent / "rerun")


@pytest.fixture(scope="module")
def converted(small_session: Written, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Entity path -> its chunks' record batches, concatenated per column name."""
    rrd = tmp_path_factory.mktemp("rrd") / "small.rrd"
    subprocess.run(
        [RERUN, "mcap", "convert", str(small_session.path), "-o", str(rrd)],
        check=True,
        capture_output=True,
    )
    columns: dict[str, dict[str, list[Any]]] = {}
    for chunk in RrdReader(rrd).stream().to_chunks():
        batch = chunk.to_record_batch()
        entity = columns.setdefault(chunk.entity_path, {})
        for field, column in zip(batch.schema, batch.columns, strict=True):
            entity.setdefault(field.name.split("@")[-1], []).extend(column.to_pylist())
    return columns


def test_no_topic_is_left_as_raw_bytes(converted: dict[str, Any]) -> None:
    raw = [entity for entity, cols in converted.items() if "McapMessage:data" in cols]
    assert raw == []


@pytest.mark.parametrize(
    ("entity", "component"),
    [
        ("/ft/wrist", "geometry_msgs.msg.WrenchStamped:message"),
        ("/controller/input", "geometry_msgs.msg.WrenchStamped:message"),
        ("/joint_states/position", "Scalars:scalars"),
        ("/joint_states/effort", "Scalars:scalars"),
        ("/trajectory/commanded/position", "Scalars:scalars"),
        ("/trajectory/desired", "InstancePoses3D:translations"),
        ("/controller/state", "hilrig_msgs.msg.ControllerState:message"),
        ("/events", "hilrig_msgs.msg.Event:message"),
        ("/diagnostics/loop", "hilrig_msgs.msg.LoopDiagnostics:message"),
    ],
)
def test_topic_is_decoded(converted: dict[str, Any], entity: str, component: str) -> None:
    assert component in converted[entity]
    assert "ros2_timestamp" in converted[entity]  # the header stamp became a timeline


def test_decoded_values_are_the_written_ones(
    converted: dict[str, Any], small_session: Written
) -> None:
    messages = [
        m
        for rows in converted["/ft/wrist"]["geometry_msgs.msg.WrenchStamped:message"]
        for m in rows
    ]
    written = [s for s in small_session.of("/ft/wrist") if isinstance(s, WrenchSample)]
    assert len(messages) == len(written)
    first = messages[0]["wrench"]["force"]
    assert (first["x"], first["y"], first["z"]) == written[0].force
    joints = converted["/joint_states/position"]["Scalars:scalars"]
    assert len(joints) == len(small_session.of("/joint_states"))


def test_rerun_builds_the_robot_from_robot_description(converted: dict[str, Any]) -> None:
    assert "TextDocument:text" in converted["/robot_description"]
    assert "CoordinateFrame:frame" in converted["/aubo_i5"]  # the URDF's robot, by name


def test_session_metadata_reaches_rerun(converted: dict[str, Any]) -> None:
    metadata = converted["/__mcap_metadata"]
    assert "session" in metadata
    assert "S012" in str(metadata["session"])


def test_rerun_check_finds_no_issue(small_session: Written) -> None:
    done = subprocess.run(
        [RERUN, "mcap", "check", str(small_session.path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
