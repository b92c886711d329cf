"""Sessions without contact on each task: the loop commands the task as it was checked (one
tick, one period of the task's time, whatever the ticks' timing) and the safety clamp never
engages but where a link's fault made the robot hold; a task beyond the limits is refused
before anything starts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.errors import ParameterError
from hilrig.recording import load
from hilrig.recording.samples import EventKind
from hilrig.rig import SessionConfig, SessionResult, record_session
from hilrig.robot import RobotModel
from hilrig.tick.links import COMMAND_LINK, ROBOT_LINK, SENSOR_LINK
from hilrig.tick.trajectory import make_trajectory

RATE_HZ = 1000.0
TASKS = {
    "circle": {},
    "square": {},
    "waypoints": {"points": [(1.5, -0.05, 0.03, 0.02), (3.0, 0.0, 0.0, 0.0)]},
}
# a link's fault holds the robot (a controlled stop) and its end resumes tracking from where the
# stop got to: both engage the clamp, at the fault or up to a failed write's 50 ms hold after it
AFTER_FAULT_NS = 100_000_000


def record(tmp: Path, task: str) -> SessionResult:
    config = SessionConfig(
        out=tmp / f"{task}.mcap",
        subject_id="S001",
        scenario="none",
        duration_s=3.5,
        trajectory=task,
        trajectory_options=TASKS[task],
    )
    return record_session(config)


@pytest.mark.parametrize("task", list(TASKS))
def test_a_session_without_contact_follows_its_task_tick_by_tick_and_never_clamps(
    tmp_path: Path, task: str
) -> None:
    result = record(tmp_path, task)
    frames = load(result.path, topics=["/trajectory/desired", "/diagnostics/loop"])
    desired = frames["/trajectory/desired"][[f"pose.position.{a}" for a in "xyz"]].to_numpy()
    ticks = frames["/diagnostics/loop"]["tick"].to_numpy()
    assert len(ticks) > 1000
    # the task at tick k is the task k periods after the start, as the clamp counts time
    trajectory = make_trajectory(task, RobotModel().fk(np.array(HOME_Q_RAD)), **TASKS[task])
    expected = np.zeros((len(ticks), 3))
    for row, tick in zip(expected, ticks, strict=True):
        trajectory.desired(tick / RATE_HZ, row)
    np.testing.assert_allclose(desired, expected, rtol=0, atol=1e-12)
    faults = [
        e.t_ns
        for e in result.events
        if e.source in (SENSOR_LINK, ROBOT_LINK, COMMAND_LINK) and e.kind == EventKind.FAULT
    ]
    clamped = [e for e in result.events if e.source == "safety"]
    unexplained = [
        e for e in clamped if not any(0 <= e.t_ns - t_ns <= AFTER_FAULT_NS for t_ns in faults)
    ]
    assert unexplained == [], unexplained


def test_a_task_beyond_the_limits_is_refused_before_anything_starts(tmp_path: Path) -> None:
    config = SessionConfig(
        out=tmp_path / "fast.mcap",
        subject_id="S001",
        trajectory="circle",
        trajectory_options={"period_s": 2.0},
    )
    with pytest.raises(ParameterError) as refused:
        record_session(config)
    assert str(refused.value) == (
        "trajectory 'circle': joint 4 acceleration 3.27 rad/s^2 is 36 % over 80 % of its "
        "limit (2.4 of 3 rad/s^2); try a longer period_s or ramp_s, or a smaller radius_m"
    )
    assert list(tmp_path.iterdir()) == []
