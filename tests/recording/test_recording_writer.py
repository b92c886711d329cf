"""The session writer: refusals, shapes per channel, crash-safe flushing; pseudonymous subjects."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from recording_helpers import session_info

from hilrig.errors import RecordingError
from hilrig.recording import (
    ChannelSpec,
    ControllerSample,
    JointSample,
    MessageType,
    PoseSample,
    SessionInfo,
    SessionWriter,
    WrenchSample,
    default_channels,
    load,
    read,
    validate_subject_id,
)
from hilrig.recording.msgdef import dependencies, full_definition, parse_schema

T0 = session_info().start_monotonic_ns


@pytest.mark.parametrize("subject", ["S012", "AB123", "XYZ98765", "P01"])
def test_pseudonyms_are_accepted(subject: str) -> None:
    assert validate_subject_id(subject) == subject


@pytest.mark.parametrize(
    "subject", ["John", "Anna Meier", "s012", "S1", "S123456", "ABCD12", "S012\n", "", "12S"]
)
def test_anything_else_is_refused_in_one_line(subject: str) -> None:
    with pytest.raises(RecordingError) as caught:
        validate_subject_id(subject)
    message = str(caught.value)
    assert "\n" not in message
    assert repr(subject) in message and "pseudonym like S012" in message


def test_session_refuses_a_personal_name() -> None:
    with pytest.raises(RecordingError, match="'Maria' is not a pseudonym"):
        SessionInfo.starting_now(session_id="s", subject_id="Maria", rig="r", controller="c")


def test_session_metadata_round_trips() -> None:
    info = session_info()
    assert SessionInfo.from_metadata(info.to_metadata(part=3)) == info
    assert info.to_metadata(part=3)["part"] == "3"


def writer(path: Path, **options: object) -> SessionWriter:
    return SessionWriter(path, session_info(), channels=default_channels(), **options)  # type: ignore[arg-type]


def test_an_existing_file_is_never_overwritten(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(RecordingError, match=r"s\.mcap: already exists; refusing to overwrite"):
        writer(path)
    assert path.read_bytes() == b"precious"


def test_samples_that_do_not_fit_their_channel_are_refused(tmp_path: Path) -> None:
    with writer(tmp_path / "s.mcap") as w:
        wrench = WrenchSample(T0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0))
        with pytest.raises(RecordingError, match="/joint_states takes JointSample, got Wrench"):
            w.write("/joint_states", wrench)
        with pytest.raises(RecordingError, match="joint arrays must have lengths"):
            w.write("/trajectory/commanded", JointSample(T0, [0.0] * 6, [0.0] * 6))
        with pytest.raises(RecordingError, match="need device_t_ns and device_seq"):
            w.write("/joint_states", JointSample(T0, [0.0] * 6, [0.0] * 6, [0.0] * 6))
        with pytest.raises(RecordingError, match="cannot write to /nope"):
            w.write("/nope", wrench)
        with pytest.raises(RecordingError, match="already registered"):
            w.add_channel(ChannelSpec("/ft/wrist", MessageType.WRENCH))
    with pytest.raises(RecordingError, match="chunk_span_s must be in"):
        writer(tmp_path / "t.mcap", chunk_span_s=1.0)


def test_flush_makes_everything_so_far_readable_before_close(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    w = writer(path)
    for i in range(30):
        w.write("/trajectory/desired", PoseSample(T0 + i * 1000, (i, 0.0, 0.0), (0, 0, 0, 1)))
    w.flush()
    loaded = read(path)  # the writer is still open: no summary yet
    assert len(loaded.frames["/trajectory/desired"]) == 30
    assert "unfinished recording" in loaded.problems[0]
    w.close()
    assert read(path).problems == ()


def test_packaged_definitions_carry_every_dependency() -> None:
    assert dependencies("geometry_msgs/msg/PoseStamped") == [
        "std_msgs/Header",
        "builtin_interfaces/Time",
        "geometry_msgs/Pose",
        "geometry_msgs/Point",
        "geometry_msgs/Quaternion",
    ]
    for kind in MessageType:
        text = full_definition(kind.value)
        defs = parse_schema(kind.value, text)
        assert set(defs) == {kind.value.replace("/msg/", "/"), *dependencies(kind.value)}
        assert DecoderFactory().decoder_for("cdr", _schema(kind.value, text)) is not None


def _schema(name: str, text: str) -> object:
    from mcap.records import Schema

    return Schema(id=1, name=name, encoding="ros2msg", data=text.encode())


names = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_0123456789", min_size=1, max_size=12)
finite = st.floats(allow_nan=False, width=64)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    axes=st.lists(names, min_size=1, max_size=9, unique=True),
    controller=names,
    frame=st.text(max_size=20),
    data=st.data(),
)
def test_any_axis_set_round_trips_through_both_readers(
    axes: list[str], controller: str, frame: str, data: st.DataObject
) -> None:
    n = len(axes)
    spec = ChannelSpec(
        "/controller/state",
        MessageType.CONTROLLER_STATE,
        frame_id=frame,
        names=tuple(axes),
        controller=controller,
    )
    ticks = [
        ControllerSample(
            T0 + i,
            *(data.draw(st.lists(finite, min_size=n, max_size=n)) for _ in range(7)),
            data.draw(st.lists(st.integers(0, 3), min_size=n, max_size=n)),
        )
        for i in range(data.draw(st.integers(1, 5)))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.mcap"
        with SessionWriter(path, session_info(), channels=[spec]) as w:
            for tick in ticks:
                w.write(spec.topic, tick)
        frame_ = load(path)[spec.topic]
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            decoded = [m.decoded_message for m in reader.iter_decoded_messages()]
    assert [d.axis_names for d in decoded] == [axes] * len(ticks)
    assert all(d.header.frame_id == frame and d.controller == controller for d in decoded)
    for field in ("force", "offset", "offset_rate", "damping", "stiffness", "chi", "zeta"):
        expected = [getattr(t, field) for t in ticks]
        assert [list(getattr(d, field)) for d in decoded] == expected
        assert np.array_equal(frame_[[f"{field}_{i}" for i in range(n)]], expected)
    assert np.array_equal(
        frame_[[f"contact_state_{i}" for i in range(n)]], [t.contact_state for t in ticks]
    )
    assert [frame_[f"axis_names_{i}"].iloc[0] for i in range(n)] == axes
