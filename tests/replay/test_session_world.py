"""When a recorded joint state was sampled: the robot's timestamps on the log clock, whatever
bunching the loop's reads put into the receive times."""

from __future__ import annotations

import numpy as np
import pandas as pd

from hilrig.replay.session_world import collision_windows, sample_times_ns


def frame(log_ns: np.ndarray, device_ns: np.ndarray) -> pd.DataFrame:
    return pd.DataFrame({"publish_time_ns": device_ns}, index=pd.Index(log_ns))


def test_bunched_receive_times_become_the_robot_s_sampling_times() -> None:
    device = np.arange(0, 30_000_000_000, 1_000_000, dtype=np.int64)  # 30 s at 1 kHz
    read_ns = 3_000_000  # the loop reads every 3 ms: up to three states at once
    log = 5_000_000_000_000 + 150_000 + -(-device // read_ns) * read_ns
    assert np.all(np.diff(log) >= 0) and len(np.unique(log)) < len(log) / 2
    times = sample_times_ns(frame(log, device))
    np.testing.assert_array_equal(times, 5_000_000_000_000 + device + 150_000)


def test_a_drifting_robot_clock_is_followed_window_by_window() -> None:
    device = np.arange(0, 60_000_000_000, 1_000_000, dtype=np.int64)
    drift = device // 20_000  # 50 ppm: 3 ms over a minute
    log = 1_000_000_000 + device + drift + 200_000  # the least delay, 0.2 ms, all along
    times = sample_times_ns(frame(log, device))
    np.testing.assert_allclose(times, log, atol=1_000)  # within 1 us of the truth throughout


def test_a_recording_without_robot_timestamps_keeps_its_log_times() -> None:
    log = np.array([10, 20, 30], dtype=np.int64)
    np.testing.assert_array_equal(sample_times_ns(frame(log, log)), log)


def test_collisions_are_runs_of_strong_force_with_a_hysteresis() -> None:
    t = np.arange(0.0, 10.0, 0.001)
    force = np.zeros((len(t), 3))
    force[(t > 2.0) & (t < 2.5), 0] = 10.0  # a push,
    force[(t >= 2.5) & (t < 3.0), 0] = 0.5  # the robot yielding: weak but not gone,
    force[(t > 3.2) & (t < 3.4), 0] = 8.0  # the robot back into the hand: the same collision
    force[(t > 7.0) & (t < 7.3), 1] = 9.0  # another one
    windows = collision_windows(t, force)
    assert [(round(t[a], 3), round(t[b - 1], 3)) for a, b in windows] == [
        (1.701, 3.698), (6.701, 7.599)]  # fmt: skip
