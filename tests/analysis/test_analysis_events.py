"""Collision events: threshold, debounce, merge, axis groups; never overlapping, ever."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hilrig.analysis import AxisGroup, CollisionEvent, EventConfig, detect, detect_group
from hilrig.errors import AnalysisError

DT = 0.001


def _pulses(t_s: np.ndarray, *spans: tuple[float, float], level: float = 1.0) -> np.ndarray:
    """``level`` on each [start, stop) span (s), 0 elsewhere."""
    out = np.zeros_like(t_s)
    for start, stop in spans:
        out[(t_s >= start - 1e-9) & (t_s < stop - 1e-9)] = level
    return out


T = np.arange(3000) * DT


def test_an_event_runs_from_the_first_sample_above_delta_to_the_first_back_below() -> None:
    magnitude = _pulses(T, (1.0, 1.5), level=2.0)
    (event,) = detect_group(T, magnitude, AxisGroup.CARTESIAN)
    assert event == CollisionEvent(AxisGroup.CARTESIAN, 1.0, 1.5, 2.0)
    assert event.duration_s == pytest.approx(0.5)


def test_the_threshold_is_strict_a_force_at_delta_is_no_collision() -> None:
    magnitude = _pulses(T, (1.0, 1.5), level=0.2)
    assert detect_group(T, magnitude, AxisGroup.CARTESIAN, EventConfig(delta=0.2)) == ()
    assert len(detect_group(T, magnitude, AxisGroup.CARTESIAN, EventConfig(delta=0.19))) == 1


def test_debounce_drops_spikes_shorter_than_the_minimum_duration() -> None:
    # a 5 ms spike, a 19 ms blip and a 20 ms touch
    magnitude = _pulses(T, (0.5, 0.505), (1.0, 1.019), (2.0, 2.02))
    found = detect_group(T, magnitude, AxisGroup.JOINT, EventConfig(debounce_s=0.02))
    assert [(e.start_s, e.end_s) for e in found] == [(2.0, 2.02)]
    assert len(detect_group(T, magnitude, AxisGroup.JOINT, EventConfig(debounce_s=0.0))) == 3


def test_events_closer_than_the_merge_gap_become_one() -> None:
    # gaps of 30 ms (merged) and 60 ms (kept apart)
    magnitude = _pulses(T, (1.0, 1.1), (1.13, 1.2), (1.26, 1.4))
    magnitude[1150] = 3.0  # the peak is the merged event's largest magnitude
    config = EventConfig(merge_gap_s=0.05, debounce_s=0.0)
    found = detect_group(T, magnitude, AxisGroup.CARTESIAN, config)
    spans = [(e.start_s, e.end_s, e.peak) for e in found]
    assert spans == [(1.0, 1.2, 3.0), (1.26, pytest.approx(1.4), 1.0)]


def test_merging_comes_before_debouncing_so_chattering_contact_survives() -> None:
    # 10 ms on, 10 ms off, five times: each piece is short, the touch is 90 ms long
    spans = [(1.0 + 0.02 * k, 1.01 + 0.02 * k) for k in range(5)]
    found = detect_group(T, _pulses(T, *spans), AxisGroup.CARTESIAN, EventConfig())
    assert [(e.start_s, round(e.end_s, 9)) for e in found] == [(1.0, 1.09)]


def test_noise_spikes_close_together_never_add_up_to_an_event() -> None:
    # a 1 ms spike every 30 ms for 0.3 s: one merged stretch, but only 10 ms above delta
    magnitude = np.zeros_like(T)
    magnitude[1000:1300:30] = 1.0
    assert detect_group(T, magnitude, AxisGroup.CARTESIAN, EventConfig()) == ()
    magnitude[1000:1300:3] = 1.0  # 100 ms above: a collision from the first to the last spike
    (event,) = detect_group(T, magnitude, AxisGroup.CARTESIAN, EventConfig())
    assert (event.start_s, event.end_s) == (1.0, pytest.approx(1.298))


def test_contact_until_the_data_ends_closes_one_interval_after_the_last_sample() -> None:
    magnitude = _pulses(T, (2.9, 4.0))
    (event,) = detect_group(T, magnitude, AxisGroup.CARTESIAN)
    assert event.end_s == pytest.approx(3.0)


def test_cartesian_group_uses_the_force_norm_and_joints_the_largest_torque() -> None:
    force = np.zeros((T.shape[0], 9))
    force[1000:1100, 0] = force[1000:1100, 1] = 0.15  # |f| = 0.212 N > 0.2 although each < 0.2
    force[2000:2100, 3] = 0.15  # tau 0.15, 0.15 on two joints: no collision (max, not norm)
    force[2000:2100, 4] = -0.15
    force[2500:2600, 8] = -0.3  # joint6
    axes = ("x", "y", "z", "joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
    found = detect(T, force, axes)
    assert [(e.group, e.start_s) for e in found] == [
        (AxisGroup.CARTESIAN, 1.0),
        (AxisGroup.JOINT, 2.5),
    ]
    assert found[0].peak == pytest.approx(0.15 * np.sqrt(2))
    assert found[1].peak == pytest.approx(0.3)


def test_groups_overlap_in_time_independently_and_come_in_start_order() -> None:
    force = np.zeros((T.shape[0], 2))
    force[1500:2500, 0] = 1.0  # joint3
    force[1000:2000, 1] = 1.0  # y
    found = detect(T, force, ("joint3", "y"))
    assert [(e.group, e.start_s, e.end_s) for e in found] == [
        (AxisGroup.CARTESIAN, 1.0, 2.0),
        (AxisGroup.JOINT, 1.5, 2.5),
    ]


def test_unknown_axes_and_bad_settings_are_refused() -> None:
    with pytest.raises(AnalysisError, match="unknown axis 'w'"):
        detect(T, np.zeros((T.shape[0], 1)), ("w",))
    with pytest.raises(AnalysisError) as err:
        EventConfig(debounce_s=-1.0)
    assert str(err.value) == "event debounce_s must be finite and >= 0, got -1.0"
    with pytest.raises(AnalysisError, match="does not match"):
        detect(T, np.zeros((5, 1)), ("x",))


@settings(max_examples=200, deadline=None)
@given(
    magnitude=arrays(np.float64, st.integers(2, 400), elements=st.floats(0.0, 1.0)),
    delta=st.floats(0.0, 1.0),
    debounce_s=st.floats(0.0, 0.05),
    merge_gap_s=st.floats(0.0, 0.05),
)
def test_events_never_overlap_and_each_holds_a_sample_above_delta(
    magnitude: np.ndarray, delta: float, debounce_s: float, merge_gap_s: float
) -> None:
    t_s = np.arange(magnitude.shape[0]) * DT
    config = EventConfig(delta=delta, debounce_s=debounce_s, merge_gap_s=merge_gap_s)
    found = detect_group(t_s, magnitude, AxisGroup.CARTESIAN, config)
    ends = [e.end_s for e in found]
    starts = [e.start_s for e in found]
    assert all(end <= start for end, start in zip(ends, starts[1:], strict=False))
    for event in found:
        inside = magnitude[(t_s >= event.start_s) & (t_s < event.end_s - 1e-12)]
        assert (inside > delta).sum() * DT >= debounce_s - 1e-12
        assert event.peak == inside.max() > delta
        assert magnitude[t_s == event.start_s][0] > delta
