"""MCAP inputs: exactly what the controller saw, or the loop's inputs when the state is absent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from replay_helpers import (
    AXES,
    CHANNELS,
    EXAMPLE,
    START_MONO_NS,
    collision,
    session_info,
    write_input_session,
)

from hilrig.recording import SessionWriter, load
from hilrig.replay import ReplayError, load_trace


def test_a_recording_replays_its_controller_state_force_columns() -> None:
    trace = load_trace(EXAMPLE)
    state = load(EXAMPLE, topics="/controller/state")["/controller/state"]
    assert trace.axis_names == AXES
    assert trace.dt_s == 1 / 500  # the recorded loop's rate_hz, not the jittery log times
    np.testing.assert_array_equal(trace.force, state[[f"force_{i}" for i in range(9)]].to_numpy())
    log_ns = state.index.to_numpy()
    assert trace.t0_ns == log_ns[0]
    np.testing.assert_array_equal(trace.t_s, (log_ns - log_ns[0]) / 1e9)
    assert trace.session is not None and trace.session.subject_id == "S001"
    assert trace.source == f"{EXAMPLE}:/controller/state"


def test_without_controller_state_the_input_and_the_latest_joint_state_are_replayed(
    tmp_path: Path,
) -> None:
    force = collision(400, 0.001)
    path = write_input_session(tmp_path / "inputs.mcap", force[:, :3], force[:, 3:])
    trace = load_trace(path)
    assert trace.axis_names == AXES
    assert trace.source.endswith("/controller/input + /joint_states effort")
    np.testing.assert_array_equal(trace.force, force)  # each tick got the frame before it
    assert trace.dt_s == 0.001


def test_joint_frames_after_a_tick_are_not_used_before_it(tmp_path: Path) -> None:
    force = collision(50, 0.001)
    # every joint frame arrives 0.3 ms after its tick: a tick uses the previous tick's frame
    path = write_input_session(
        tmp_path / "late.mcap", force[:, :3], force[:, 3:], joint_lead_ns=-300_000
    )
    trace = load_trace(path)
    np.testing.assert_array_equal(trace.force[1:, 3:], force[:-1, 3:])
    np.testing.assert_array_equal(trace.force[0, 3:], force[0, 3:])  # before any: the first


def test_the_wrist_wrench_alone_is_a_cartesian_trace(tmp_path: Path) -> None:
    force = collision(100, 0.001, axes=3)
    trace = load_trace(write_input_session(tmp_path / "wrist.mcap", force, None))
    assert trace.axis_names == ("x", "y", "z")
    np.testing.assert_array_equal(trace.force, force)


def test_a_recording_without_controller_topics_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "no-controller.mcap"
    with SessionWriter(path, session_info(), channels=[CHANNELS["/ft/wrist"]]):
        pass
    with pytest.raises(ReplayError) as caught:
        load_trace(path)
    assert str(caught.value) == (
        f"{path}: no /controller/state or /controller/input to replay (has /ft/wrist)"
    )


def test_a_file_that_is_not_mcap_is_refused_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "fake.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + b"\0" * 10)
    with pytest.raises(ReplayError) as caught:
        load_trace(path)
    assert str(caught.value).startswith(f"{path}") and "\n" not in str(caught.value)


def test_log_times_start_the_time_axis(tmp_path: Path) -> None:
    force = collision(10, 0.001, axes=3)
    trace = load_trace(write_input_session(tmp_path / "t.mcap", force, None, period_ns=2_000_000))
    assert trace.t0_ns == START_MONO_NS + session_info().clock_offset_ns
    np.testing.assert_allclose(trace.t_s, np.arange(10) * 0.002)
