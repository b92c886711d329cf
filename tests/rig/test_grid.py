"""The loop's nominal grid: it holds the sensor's schedule through late frames, follows a slow
sensor clock, drops an odd early frame's anchor within its fast window, and never hides a
delay shorter than its threshold."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from hilrig.rig.grid import FAST_SHIFT_NS, FAST_WINDOW, GRID_WINDOW, NominalGrid

P = 1_000_000
START = 5_000_000_000


def lateness_of(arrivals: list[tuple[int, int]], grid: NominalGrid | None = None) -> list[int]:
    """Each tick's lateness for (start time, frames read) pairs."""
    grid = NominalGrid(P, START) if grid is None else grid
    return [now - grid.place(now, frames) for now, frames in arrivals]


def on_schedule(first: int, count: int, delay_ns: int = 0) -> list[tuple[int, int]]:
    """``count`` frames one period apart from frame ``first``, each read ``delay_ns`` late."""
    return [(START + (first + k) * P + delay_ns, 1) for k in range(count)]


def test_late_frames_keep_the_schedule_and_read_late() -> None:
    delays = [0, 30_000, 250_000, 5_000, 900_000, 0, 70_000]
    arrivals = [(START + (k + 1) * P + d, 1) for k, d in enumerate(delays)]
    assert lateness_of(arrivals) == delays


def test_frames_read_together_advance_the_grid_by_as_many_periods() -> None:
    arrivals = [*on_schedule(1, 3), (START + 5 * P + 20_000, 2), *on_schedule(6, 2)]
    assert lateness_of(arrivals) == [0, 0, 0, 20_000, 0, 0]


def test_a_fallback_tick_takes_the_next_period_and_the_late_frame_the_one_after() -> None:
    grid = NominalGrid(P, START)
    lateness_of(on_schedule(1, 3), grid)
    assert grid.place(START + 5 * P, 0) == START + 4 * P  # no frame: on the deadline
    assert grid.place(START + 5 * P + 10_000, 1) == START + 5 * P


def test_an_early_frame_re_anchors_the_grid() -> None:
    grid = NominalGrid(P, START + 400_000)  # the loop started 0.4 ms into the sensor's period
    assert grid.place(START + P, 1) == START + P  # the first frame came early: anchored to it
    assert lateness_of(on_schedule(2, 5), grid) == [0] * 5


def test_an_odd_early_frame_s_anchor_is_dropped_within_the_fast_window() -> None:
    # as traced on the slow machine: a read of two frames, the newer 0.8 ms ahead of schedule
    arrivals = [*on_schedule(1, 100), (START + 101 * P + 200_000, 2), *on_schedule(103, 500)]
    late = lateness_of(arrivals)
    after = late[101:]
    assert after[:FAST_WINDOW] == [800_000] * FAST_WINDOW  # wrong until found so
    assert after[FAST_WINDOW:] == [0] * (500 - FAST_WINDOW)


def test_a_delay_under_the_threshold_is_never_hidden_before_the_window_ends() -> None:
    delay = FAST_SHIFT_NS - 1_000
    arrivals = [*on_schedule(1, 1), *on_schedule(2, GRID_WINDOW - 2, delay_ns=delay)]
    grid = NominalGrid(P, START)
    assert lateness_of(arrivals, grid)[1:] == [delay] * (GRID_WINDOW - 2)
    assert grid.fast_shifts == 0


def test_a_slow_sensor_clock_is_followed() -> None:
    slow = P + 100  # 100 ppm slow: 0.1 ms behind after a window
    grid = NominalGrid(P, START)
    arrivals = [(START + k * slow, 1) for k in range(1, 10 * GRID_WINDOW)]
    late = lateness_of(arrivals, grid)
    # one window behind at most: each window's end moves it by the window's first lateness
    assert max(late) < 2 * GRID_WINDOW * 100
    assert max(late[-GRID_WINDOW:]) - min(late[-GRID_WINDOW:]) < GRID_WINDOW * 100
    assert grid.fast_shifts == 0


@given(
    st.lists(
        st.tuples(st.integers(min_value=1, max_value=5 * P), st.integers(0, 4)),
        min_size=1,
        max_size=300,
    )
)
def test_no_tick_is_placed_after_its_start_or_before_the_last(
    steps: list[tuple[int, int]],
) -> None:
    grid = NominalGrid(P, START, window=37, fast_window=11, fast_shift_ns=100_000)
    now = START
    for gap, frames in steps:
        now += gap
        before = grid.nominal_ns
        nominal = grid.place(now, frames)
        assert before <= nominal <= now
        assert grid.nominal_ns <= now
