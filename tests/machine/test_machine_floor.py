"""The machine's timing floor (``hilrig doctor``, the bench's machine suite): counts, invariants
and the summary against closed forms; no time is asserted."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hilrig.errors import HilrigError
from hilrig.machine import Timing, measure_floor, timing
from hilrig.machine.floor import delivery, pty_delivery, wake_ups
from hilrig.timing import realtime_permitted

ALLOWED = frozenset(os.sched_getaffinity(0))


def test_timing_of_1_to_100_us() -> None:
    durations = np.arange(1, 101, dtype=np.int64) * 1000
    assert timing(durations) == Timing(100, 50.5, 99.01, 100.0, 0.0)


def test_only_what_is_longer_than_a_period_counts_as_over() -> None:
    durations = np.array([1_000_000, 1_000_001, 2_000_000, 5], dtype=np.int64)
    assert timing(durations).over_a_period_pct == 50.0


@given(st.lists(st.integers(0, 10_000_000), min_size=1, max_size=200))
def test_the_share_over_a_period_is_the_count_over_it(values: list[int]) -> None:
    summary = timing(np.asarray(values, dtype=np.int64))
    assert summary.count == len(values)
    assert summary.over_a_period_pct == 100 * sum(v > 1_000_000 for v in values) / len(values)
    assert summary.p50_us <= summary.p99_us <= summary.max_us == max(values) / 1000


def test_every_wake_up_is_counted_and_none_comes_early() -> None:
    woken = wake_ups(0.3)
    assert len(woken.late_ns) == len(woken.work_ns) == 300
    assert (woken.late_ns >= 0).all()  # a sleep to a deadline never ends before it
    assert (woken.work_ns > 0).all()
    assert woken.sched_fifo == realtime_permitted()
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the thread is put back


def test_every_message_through_the_pty_comes_once_after_it_was_sent() -> None:
    delays = pty_delivery(0.3)
    assert len(delays) == 300
    assert (delays > 0).all()  # every slot filled: each index read once, after its write


def test_a_writer_that_fails_is_one_line() -> None:
    read_end, write_end = os.pipe()
    with pytest.raises(HilrigError) as caught:
        delivery(read_end, os.dup(read_end), 0.01)  # writing to a pipe's read end fails
    assert str(caught.value) == "link test: 0 of 10 messages came (writing: Bad file descriptor)"
    os.close(write_end)


@pytest.mark.parametrize("cpu", sorted(ALLOWED)[-1:])
def test_the_floor_on_one_cpu(cpu: int) -> None:
    floor = measure_floor(0.2, cpu=cpu)
    assert (floor.wake_ups.count, floor.work.count, floor.pty.count) == (200, 200, 200)
    assert floor.cpu == cpu
    assert floor.missed_at_least_pct == max(
        floor.wake_ups.over_a_period_pct, floor.pty.over_a_period_pct
    )
    assert os.sched_getaffinity(0) == ALLOWED
