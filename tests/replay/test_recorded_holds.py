"""The live loop's link flags read back from its events: against the flags the loop's own rules
give each tick, the events made by the live loop's own event detector."""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from hilrig.recording.samples import EventRecord
from hilrig.replay.recorded_holds import ALL_OK, recorded_flags
from hilrig.rig.events import EventDetector
from hilrig.tick.links import COMMAND_FAULT_HOLD_NS, COMMAND_LINK, ROBOT_LINK, SENSOR_LINK
from hilrig.tick.step_kernel import COMMAND_OK, ROBOT_OK, SENSOR_OK

# per tick: sensor fresh, robot fresh, a joint-target write failed, the clamp's flags
Tick = tuple[bool, bool, bool, int]
ticks_strategy = st.lists(
    st.tuples(
        st.sampled_from([True] * 4 + [False]),  # runs of stale and fresh ticks, mostly fresh
        st.sampled_from([True] * 4 + [False]),
        st.sampled_from([False] * 19 + [True]),
        st.sampled_from([0, 0, 0, 1, 2]),
    ),
    min_size=1,
    max_size=300,
)
gaps_strategy = st.lists(st.integers(100_000, 20_000_000), min_size=300, max_size=300)


def live(ticks: list[Tick], t_ns: np.ndarray) -> tuple[np.ndarray, pd.DataFrame]:
    """What the live loop gives each tick (loop.py, loop_step.py) and the events it logs."""
    records: list[EventRecord] = []
    detector = EventDetector(records.append)
    hold_until = 0
    flags = np.zeros(len(ticks), dtype=np.int64)
    for k, (sensor, robot, failed, clamp) in enumerate(ticks):
        start = int(t_ns[k])
        if failed:
            hold_until = start + COMMAND_FAULT_HOLD_NS
            detector.fault(COMMAND_LINK, "Modbus exception 6 (device busy)", start)
        command = start >= hold_until
        flags[k] = (SENSOR_OK * sensor) | (ROBOT_OK * robot) | (COMMAND_OK * command)
        detector.link(SENSOR_LINK, sensor, start)
        detector.link(ROBOT_LINK, robot, start)
        detector.clamp(clamp, start)  # other faults on the same ticks are not links
        if k % 97 == 5:
            detector.mark("operator", "mark", start)
    frame = pd.DataFrame(
        {
            "kind": np.array([int(r.kind) for r in records], dtype=np.uint8),
            "source": pd.Categorical([r.source for r in records]),
            "detail": pd.Categorical([r.detail for r in records]),
        },
        index=pd.Index([r.t_ns for r in records], dtype=np.int64, name="log_time_ns"),
    )
    return flags, frame


@settings(max_examples=200, deadline=None)
@given(ticks_strategy, gaps_strategy)
def test_each_tick_gets_the_flags_the_live_loop_gave_it(ticks: list[Tick], gaps: list[int]) -> None:
    t_ns = 10**12 + np.cumsum(np.asarray(gaps[: len(ticks)], dtype=np.int64))
    expected, events = live(ticks, t_ns)
    np.testing.assert_array_equal(recorded_flags(t_ns, events), expected)


def test_a_link_stale_to_the_end_stays_stale_and_no_events_mean_all_ok() -> None:
    t_ns = np.arange(10, dtype=np.int64) * 1_000_000
    ticks = [(True, True, False, 0)] * 4 + [(False, True, False, 0)] * 6
    expected, events = live(ticks, t_ns)
    flags = recorded_flags(t_ns, events)
    assert flags.tolist() == [ALL_OK] * 4 + [ROBOT_OK | COMMAND_OK] * 6 == expected.tolist()
    assert recorded_flags(t_ns, None).tolist() == [ALL_OK] * 10
    assert recorded_flags(t_ns, events.iloc[:0]).tolist() == [ALL_OK] * 10


def test_a_failed_write_holds_the_commands_for_50_ms_from_its_tick() -> None:
    t_ns = np.arange(100, dtype=np.int64) * 1_000_000  # 1 kHz
    ticks = [(True, True, k == 10, 0) for k in range(100)]
    _, events = live(ticks, t_ns)
    held = recorded_flags(t_ns, events) != ALL_OK
    assert np.flatnonzero(held).tolist() == list(range(10, 60))
