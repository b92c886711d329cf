"""--verify: a recording replays through its recorded controller exactly; a tampered one fails."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from replay_helpers import (
    EXAMPLE,
    collision,
    tampered_copy,
    write_input_session,
    write_state_session,
)

from hilrig.control import Law
from hilrig.recording import load
from hilrig.replay import ReplayError
from hilrig.replay.verify import summary_lines, verify
from hilrig.rig import SessionConfig, record_session


def test_a_real_recording_of_an_earlier_kernel_replays_to_rounding() -> None:
    # The example was recorded before the kernel's discretisation became a closed form (it was
    # a series truncated at 1e-16): today's replay differs from it by rounding only. A session
    # recorded by this code replays with zero difference (the test below).
    report = verify(EXAMPLE)
    assert report.ok
    assert report.law is Law.ADAPTIVE and report.dt_s == 0.002 and report.ticks == 3499
    assert report.params_source == "the recording's session metadata"
    assert all(d.size <= 1e-14 for d in report.largest)
    assert re.fullmatch(
        r"OK: largest difference (0|\d(\.\d+)?e-1[4-9]) \(tolerance 1e-12\)",
        summary_lines(report)[-1],
    )


def test_altered_parameter_metadata_fails_naming_the_difference_and_where(tmp_path: Path) -> None:
    report = verify(tampered_copy(tmp_path))
    assert not report.ok
    worst = report.worst
    assert worst.quantity == "damping" and worst.size == pytest.approx(10.0, rel=1e-3)
    assert worst.axis in ("x", "y", "z")
    assert worst.t_s == pytest.approx(worst.tick * 0.002, abs=0.01)
    line = summary_lines(report)[-1]
    assert line.startswith("FAILED: largest difference 10 (tolerance 1e-12) in damping of ")
    assert f"at tick {worst.tick} " in line and "recorded 1" in line and "replayed 1" in line


def test_a_recording_listing_no_parameters_is_checked_against_the_loop_defaults(
    tmp_path: Path,
) -> None:
    path = write_state_session(tmp_path / "bare.mcap", collision(1500, 0.001))
    report = verify(path)
    assert report.ok
    assert report.params_source.startswith("the live loop's defaults")


def test_a_recording_made_with_other_parameters_than_listed_fails(tmp_path: Path) -> None:
    listed = {"law": "fixed", "rate_hz": 1000.0}  # the state below was computed adaptively
    path = write_state_session(tmp_path / "other.mcap", collision(1500, 0.001), params=listed)
    report = verify(path)
    assert not report.ok
    assert report.law is Law.FIXED


def test_nothing_to_verify_without_a_recorded_state(tmp_path: Path) -> None:
    path = write_input_session(tmp_path / "in.mcap", np.zeros((5, 3)), None)
    with pytest.raises(ReplayError) as caught:
        verify(path)
    assert str(caught.value) == f"{path}: no /controller/state: nothing recorded to verify against"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh 1 kHz session on the emulated rig: a body collision from 3.5 s to 5.5 s."""
    out = tmp_path_factory.mktemp("recorded") / "session.mcap"
    record_session(SessionConfig(out=out, subject_id="S004", scenario="paper-body", duration_s=5.0))
    return out


def test_a_session_recorded_now_replays_with_zero_difference(recorded: Path) -> None:
    report = verify(recorded)
    assert report.ok, summary_lines(report)
    state = load(recorded, topics=["/controller/state"])["/controller/state"]
    assert report.dt_s == 0.001 and report.ticks == len(state) > 0  # every recorded tick
    assert report.params_source == "the recording's session metadata"
    assert all(d.size == 0.0 for d in report.largest)
