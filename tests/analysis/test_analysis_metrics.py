"""Every metric on traces whose answers are worked out by hand, and properties of all traces."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hilrig.analysis import (
    DEFAULT_METRICS,
    AxisGroup,
    AxisMetrics,
    EventConfig,
    MetricsConfig,
    Run,
    detect,
    event_metrics,
    tracking_metrics,
    unit,
)
from hilrig.errors import AnalysisError

DT = 0.01
T = np.arange(400) * DT  # 4 s at 100 Hz


def _run(
    force: np.ndarray,
    offset: np.ndarray | None = None,
    rate: np.ndarray | None = None,
    *,
    axis: str = "x",
    t_s: np.ndarray = T,
    **commanded: np.ndarray,
) -> Run:
    def column(values: np.ndarray | None) -> np.ndarray:
        return np.zeros((t_s.shape[0], 1)) if values is None else values.reshape(-1, 1)

    return Run("r", "fixed", (axis,), t_s, column(force), column(offset), column(rate), **commanded)


def _triangle(t_s: np.ndarray, peak: float = 10.0) -> np.ndarray:
    """peak * (1 - |t - 1|) on [0, 2], 0 elsewhere: area = peak (N*s)."""
    return np.where(np.abs(t_s - 1.0) < 1.0, peak * (1.0 - np.abs(t_s - 1.0)), 0.0)


def _one(run: Run, delta: float = 0.05, config: MetricsConfig = DEFAULT_METRICS) -> AxisMetrics:
    events = detect(run.t_s, run.force, run.axes, EventConfig(delta=delta, debounce_s=0.0))
    (metrics,) = event_metrics(run, events, config)
    return metrics


def test_impulse_of_a_triangular_pulse_is_its_area_and_the_peak_is_signed() -> None:
    m = _one(_run(-_triangle(T)))
    assert (m.start_s, m.end_s) == (pytest.approx(0.01), pytest.approx(2.0))
    assert m.impulse == pytest.approx(-10.0, rel=1e-12)
    assert m.peak_force == pytest.approx(-10.0)


def test_impulse_covers_the_samples_either_side_of_the_threshold_crossings() -> None:
    # delta 0.25: the event is 0.03 .. 1.97 s (end 1.98); integrated from 0.02 to 1.98 s, which
    # leaves out the two 0.02 s tails below 0.2 N: 10 - 2 * (0.2 * 0.02 / 2) = 9.996 N*s
    m = _one(_run(_triangle(T)), delta=0.25)
    assert (m.start_s, m.end_s) == (pytest.approx(0.03), pytest.approx(1.98))
    assert m.impulse == pytest.approx(9.996, rel=1e-12)


def _pushed_then_released() -> np.ndarray:
    """Offset (m) for the triangle's event (0.01 .. 2.0 s): -0.03 m at row 150 (its time 1.51
    s), then, from the row whose offset belongs to 2.0 s (199), a return that leaves the 1 mm
    band twice: out to row 209, in, out 220-229, in, out 240-249, inside from row 250 on."""
    offset = np.zeros(T.shape[0])
    offset[1:151] = np.linspace(0.0, -0.03, 151)[1:]
    offset[151:199] = np.linspace(-0.03, 0.02, 49)[1:]
    offset[199:210] = 0.02
    offset[210:220] = 0.0005
    offset[220:230] = 0.002
    offset[230:240] = -0.0008
    offset[240:250] = -0.0015
    offset[250:] = 0.0009
    return offset


def test_max_offset_is_signed_and_the_response_time_runs_from_the_event_start() -> None:
    m = _one(_run(_triangle(T), _pushed_then_released()))
    assert (m.max_offset, m.max_abs_offset) == (pytest.approx(-0.03), pytest.approx(0.03))
    # offset row 150 belongs to 1.51 s; the event starts at 0.01 s
    assert m.time_to_max_offset_s == pytest.approx(1.5)


def test_recovery_waits_until_the_offset_stays_in_the_band_for_good() -> None:
    # first inside at 2.11 s, but out again twice; inside for good from row 250, i.e. 2.51 s
    m = _one(_run(_triangle(T), _pushed_then_released()))
    assert m.recovery_time_s == pytest.approx(0.51)


def test_the_band_is_two_percent_of_the_peak_when_that_exceeds_the_floor() -> None:
    offset = _pushed_then_released()
    offset[150] = -0.1  # band: max(1 mm, 2 mm) = 2 mm; 1.5 and 2 mm are inside now
    m = _one(_run(_triangle(T), offset))
    assert m.recovery_time_s == pytest.approx(0.11)  # from row 210, whose offset is at 2.11 s
    floor_only = _one(_run(_triangle(T), offset), config=MetricsConfig(recovery_fraction=0.0))
    assert floor_only.recovery_time_s == pytest.approx(0.51)


def test_recovery_is_zero_when_the_offset_is_already_back_as_the_force_goes() -> None:
    offset = _pushed_then_released()
    offset[199:] = 0.0
    assert _one(_run(_triangle(T), offset)).recovery_time_s == 0.0


def test_no_recovery_when_the_data_ends_or_the_next_event_starts_first() -> None:
    offset = _pushed_then_released()
    offset[-1] = 0.005  # outside the band at the very end
    assert _one(_run(_triangle(T), offset)).recovery_time_s is None
    force = _triangle(T) + _triangle(T - 2.25)  # next push from 2.26 s, out of the band then
    events = detect(T, force.reshape(-1, 1), ("x",), EventConfig(delta=0.05, debounce_s=0.0))
    first, second = event_metrics(_run(force, _pushed_then_released()), events)
    assert (first.event, first.recovery_time_s) == (0, None)
    assert (second.event, second.start_s) == (1, pytest.approx(2.26))


def test_contact_until_the_end_has_no_recovery() -> None:
    m = _one(_run(_triangle(T - 2.5), np.full(T.shape[0], 1e-4)))
    assert (m.end_s, m.recovery_time_s) == (pytest.approx(4.0), None)


def test_peak_offset_rate_and_commanded_joint_speed_come_from_the_event_window() -> None:
    rate = np.zeros(T.shape[0])
    rate[100] = -0.4  # inside the window
    joints = np.zeros((T.shape[0], 6))
    joints[:, 2] = np.cumsum(np.where((T > 1.0) & (T < 1.5), 0.3, 0.1) * DT)  # 0.3 rad/s
    run = _run(_triangle(T), rate=rate, commanded_t_s=T, commanded_joints_rad=joints)
    m = _one(run)
    assert m.peak_offset_rate == pytest.approx(0.4)
    assert m.peak_commanded_joint_speed_rad_s == pytest.approx(0.3)
    assert _one(_run(_triangle(T))).peak_commanded_joint_speed_rad_s is None


def test_a_late_tick_and_its_catch_up_are_no_burst_of_joint_speed() -> None:
    times = T.copy()
    times[150] = times[151] - 2e-5  # tick 150 logged late, 20 us before tick 151
    joints = np.zeros((T.shape[0], 6))
    joints[:, 0] = 0.2 * T  # 0.2 rad/s, one step per tick
    run = _run(_triangle(T), commanded_t_s=times, commanded_joints_rad=joints)
    assert _one(run).peak_commanded_joint_speed_rad_s == pytest.approx(0.2)


def test_tracking_rms_of_a_sine_outside_the_event_ignores_the_event() -> None:
    amplitude = 0.004
    offset = amplitude * np.sin(2 * np.pi * 2.0 * T)  # 2 Hz: whole periods in [0, 1) and [2, 4)
    force = np.where((T >= 1.0 - 1e-9) & (T < 2.0 - 1e-9), 5.0, 0.0)
    offset[(T >= 1.0 - 1e-9) & (T < 2.0 - 1e-9)] = 1.0  # huge while pushed: not tracking
    run = _run(force, offset)
    events = detect(T, run.force, run.axes)
    (tracking,) = tracking_metrics(run, events)
    assert tracking.samples == 300
    assert tracking.tracking_rms == pytest.approx(amplitude / np.sqrt(2), rel=1e-12)


@pytest.mark.parametrize("inside", [np.inf, np.nan], ids=["inf", "nan"])
def test_tracking_rms_ignores_values_that_are_not_finite_inside_the_event(inside: float) -> None:
    amplitude = 0.004
    offset = amplitude * np.sin(2 * np.pi * 2.0 * T)
    pushed = (T >= 1.0 - 1e-9) & (T < 2.0 - 1e-9)
    offset[pushed] = inside
    run = _run(np.where(pushed, 5.0, 0.0), offset)
    (tracking,) = tracking_metrics(run, detect(T, run.force, run.axes))
    assert tracking.tracking_rms == pytest.approx(amplitude / np.sqrt(2), rel=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    offset=arrays(np.float64, (400, 3), elements=st.floats(-1.0, 1.0)),
    start=st.integers(0, 390),
    length=st.integers(10, 200),
)
def test_tracking_rms_is_the_rms_over_the_rows_outside_the_events(
    offset: np.ndarray, start: int, length: int
) -> None:
    force = np.zeros((T.shape[0], 3))
    force[start : start + length, 0] = 5.0
    run = Run("r", "fixed", ("x", "y", "z"), T, force, offset, np.zeros_like(offset))
    events = detect(T, force, run.axes)
    inside = np.zeros(T.shape[0], dtype=bool)
    for event in events:
        inside |= (event.start_s - 1e-9 <= T) & (event.end_s - 1e-9 > T)
    for col, tracking in enumerate(tracking_metrics(run, events)):
        free = offset[~inside, col]
        assert tracking.samples == free.size
        expected = np.sqrt(np.mean(free * free)) if free.size else None
        assert tracking.tracking_rms == pytest.approx(expected, rel=1e-12, abs=1e-300)


def test_an_event_of_another_group_leaves_an_axis_alone() -> None:
    force = np.zeros((T.shape[0], 2))
    force[100:200, 1] = 1.0  # a joint collision
    run = Run("r", "fixed", ("x", "joint1"), T, force, np.zeros_like(force), np.zeros_like(force))
    events = detect(T, force, run.axes)
    assert [m.axis for m in event_metrics(run, events)] == ["joint1"]
    assert [t.samples for t in tracking_metrics(run, events)] == [400, 300]


def test_units_follow_the_axis_group() -> None:
    assert unit("impulse", AxisGroup.CARTESIAN) == "N*s"
    assert unit("impulse", "joint") == "N*m*s"
    assert unit("max_abs_offset", AxisGroup.JOINT) == "rad"
    with pytest.raises(AnalysisError, match="unknown metric"):
        unit("speed", AxisGroup.JOINT)


def test_runs_with_inconsistent_shapes_or_times_are_refused() -> None:
    with pytest.raises(AnalysisError, match="offset"):
        Run("r", "fixed", ("x",), T, np.zeros((400, 1)), np.zeros((3, 1)), np.zeros((400, 1)))
    with pytest.raises(AnalysisError, match="increasing"):
        _run(np.zeros(400), t_s=np.zeros(400))


@settings(max_examples=150, deadline=None)
@given(
    pulse=arrays(np.float64, st.integers(1, 200), elements=st.floats(1e-3, 100.0)),
    before=st.integers(1, 50),
    after=st.integers(1, 50),
)
def test_impulse_of_a_nonnegative_pulse_equals_its_trapezoid_integral(
    pulse: np.ndarray, before: int, after: int
) -> None:
    force = np.concatenate([np.zeros(before), pulse, np.zeros(after)])
    t_s = np.arange(force.shape[0]) * DT
    run = _run(force, t_s=t_s)
    events = detect(t_s, run.force, run.axes, EventConfig(delta=0.0, debounce_s=0.0))
    (m,) = event_metrics(run, events)
    assert m.impulse == pytest.approx(np.trapezoid(force, t_s), rel=1e-12)


@settings(max_examples=150, deadline=None)
@given(
    force=arrays(np.float64, st.integers(2, 300), elements=st.floats(0.0, 1.0)),
    offset_seed=st.integers(0, 2**32 - 1),
)
def test_recovery_and_response_times_are_never_negative(
    force: np.ndarray, offset_seed: int
) -> None:
    t_s = np.arange(force.shape[0]) * DT
    offset = np.random.default_rng(offset_seed).normal(scale=0.002, size=force.shape[0])
    run = _run(force, offset, t_s=t_s)
    events = detect(t_s, run.force, run.axes, EventConfig(delta=0.5, debounce_s=0.0))
    for m in event_metrics(run, events):
        assert m.recovery_time_s is None or m.recovery_time_s >= 0.0
        assert 0.0 < m.time_to_max_offset_s <= t_s[-1] + DT - m.start_s + 1e-12


@pytest.mark.parametrize("field", ["recovery_floor", "recovery_fraction"])
def test_bad_recovery_settings_are_refused(field: str) -> None:
    with pytest.raises(AnalysisError) as err:
        MetricsConfig(**{field: float("nan")})
    assert str(err.value) == f"{field} must be finite and >= 0, got nan"


def test_units_of_unknown_metrics_and_groups_are_refused() -> None:
    assert unit("impulse", "joint") == "N*m*s"
    with pytest.raises(AnalysisError) as err:
        unit("impulse", "wrist")
    assert str(err.value) == "unknown axis group 'wrist'; known: cartesian, joint"
