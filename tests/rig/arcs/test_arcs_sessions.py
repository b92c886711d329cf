"""Sessions on the ARCS link (the default), end to end: AUBO's client in the link's process, the
emulated ARCS controller in the rig's. Each of the controller's faults ends the session with one
line and an event, leaves servo mode and keeps the file whole; a stalled RTDE stream holds the
robot; a refused login starts nothing."""

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from hilrig.errors import LinkError
from hilrig.recording import load
from hilrig.recording.samples import EventKind
from hilrig.rig import ControlLoop, RigProcess, SessionConfig, SessionResult, record_session
from hilrig.rig.arcs.settings import ArcsSettings
from hilrig.rig.kinds import RobotLinkKind

During = Callable[[RigProcess, ControlLoop], None]


def run(
    tmp: Path,
    name: str,
    seconds: float,
    *,
    during: During | None = None,
    arcs: ArcsSettings | None = None,
) -> SessionResult:
    """Record a session on the ARCS link; ``during`` runs in a thread once the loop ticks."""
    rigs: list[RigProcess] = []
    errors: list[BaseException] = []

    def on_start(loop: ControlLoop) -> None:
        def target() -> None:
            try:
                assert during is not None
                during(rigs[0], loop)
            except BaseException as err:  # reported by the test, not lost in the thread
                errors.append(err)

        if during is not None:
            threading.Thread(target=target, daemon=True).start()

    config = SessionConfig(
        out=tmp / name,
        subject_id="S001",
        duration_s=seconds,
        robot_link=RobotLinkKind.ARCS,
        arcs=arcs or ArcsSettings(),
    )
    result = record_session(config, on_start=on_start, rig_ready=rigs.append)
    assert errors == []
    return result


def after_ticks(ticks: int, fault: str, *args: object) -> During:
    """Inject ``fault`` once the loop has ticked ``ticks`` times."""

    def during(rig: RigProcess, loop: ControlLoop) -> None:
        while loop.summary.ticks < ticks:
            time.sleep(0.005)
        rig.fault(fault, *args)

    return during


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> SessionResult:
    return run(tmp_path_factory.mktemp("arcs"), "arcs.mcap", 3.0)


def test_every_rtde_sample_is_recorded_and_servo_mode_is_left(session: SessionResult) -> None:
    counters = session.rig_counters
    assert counters is not None
    frames = load(session.path)
    assert len(frames["/joint_states"]) == counters.rtde_samples_sent > 0
    # the servo stream ran: several servoJoint calls per 100 ticks (200 Hz against 1 kHz)
    assert counters.servo_joints >= session.summary.ticks // 10
    assert counters.servo_mode is False
    assert session.ended_by == "duration reached"
    assert session.drops == 0


def test_every_servo_call_is_recorded_with_targets_a_tick_commanded(
    session: SessionResult,
) -> None:
    counters = session.rig_counters
    assert counters is not None
    frames = load(session.path, topics=["/robot/servo", "/trajectory/commanded"])
    servo, commanded = frames["/robot/servo"], frames["/trajectory/commanded"]
    columns = [f"position_{j}" for j in range(6)]
    # every call the link made is in the file, and the controller took each one
    assert len(servo) == session.robot_link["servo_calls"] == counters.servo_joints
    assert np.all(np.diff(servo.index.to_numpy()) > 0)
    # each call carried the targets of a tick that had started before it left, as the tick
    # wrote them, and later calls never carry an earlier tick's (the first ones, before the
    # loop's first targets, hold the start pose)
    sent, ticks = servo[columns].to_numpy(), commanded[columns].to_numpy()
    t_sent, t_ticks = servo.index.to_numpy(), commanded.index.to_numpy()
    ticks_of: dict[bytes, list[int]] = {}
    for k, row in enumerate(ticks):
        ticks_of.setdefault(row.tobytes(), []).append(k)
    latest, after_the_first_ticks = -1, np.searchsorted(t_sent, t_ticks[1])
    for t, row in zip(t_sent[after_the_first_ticks:], sent[after_the_first_ticks:], strict=True):
        started = [k for k in ticks_of.get(row.tobytes(), []) if t_ticks[k] <= t]
        assert started, f"a servo call at {t} ns carried no tick's targets"
        assert started[-1] >= latest  # in the ticks' order
        latest = started[-1]


def test_the_recording_says_which_link_and_never_the_password(session: SessionResult) -> None:
    with session.path.open("rb") as stream:  # the official reader
        attached = {a.name: a.data for a in make_reader(stream).iter_attachments()}
    config = json.loads(attached["config.json"])
    assert config["robot_link"] == "arcs"
    assert config["arcs"]["servo_rate_hz"] == 200.0
    assert "password" not in config["arcs"]
    assert b"123456" not in session.path.read_bytes()


@pytest.mark.parametrize(
    ("fault", "ended_by"),
    [
        ("arcs.protective_stop", "robot: the controller reports protective stop (safety mode 5)"),
        (
            "arcs.emergency_stop",
            "robot: the controller reports robot emergency stop (safety mode 8)",
        ),
        (
            "arcs.servo_timeout",
            "robot: the controller refused servoJoint (code -13): not in servo mode",
        ),
    ],
)
def test_a_controller_fault_ends_the_session_with_one_line_and_an_event(
    tmp_path: Path, fault: str, ended_by: str
) -> None:
    result = run(tmp_path, "fault.mcap", 20.0, during=after_ticks(500, fault))
    assert result.ended_by == ended_by
    assert "\n" not in result.ended_by
    assert result.summary.ticks < 15_000  # ended by the fault, not by its duration
    counters = result.rig_counters
    assert counters is not None and counters.servo_mode is False
    frames = load(result.path)  # the file is whole: the official reader takes it
    faults = [e for e in result.events if e.kind is EventKind.FAULT and e.source == "session"]
    assert [e.detail for e in faults] == [f"{ended_by}: robot held, session ended"]
    assert len(frames["/events"]) == len(result.events)


def test_a_lost_link_ends_the_session_with_the_client_s_reason(tmp_path: Path) -> None:
    result = run(tmp_path, "dropped.mcap", 20.0, during=after_ticks(500, "arcs.drop_links"))
    assert result.ended_by.startswith("robot: servoJoint failed 3 times in a row: ")
    assert "\n" not in result.ended_by
    assert result.summary.ticks < 15_000
    assert result.robot_link["servo_calls_unanswered"] == 3
    faults = [e.detail for e in result.events if e.source == "session"]
    assert faults == [f"{result.ended_by}: robot held, session ended"]
    load(result.path)  # whole


def test_a_stalled_rtde_stream_holds_the_robot_and_the_session_goes_on(tmp_path: Path) -> None:
    result = run(tmp_path, "stall.mcap", 2.5, during=after_ticks(500, "arcs.stall_rtde", 0.1))
    assert result.ended_by == "duration reached"
    assert result.summary.hold_ticks > 0
    robot = [e.detail for e in result.events if e.source == "robot joint state"]
    assert robot[:2] == [
        "stale or lost: the robot holds its pose until the data is fresh again",
        "data fresh again: tracking resumes",
    ]


def test_a_refused_login_starts_nothing_and_says_why(tmp_path: Path) -> None:
    with pytest.raises(LinkError) as err:
        run(tmp_path, "refused.mcap", 1.0, arcs=ArcsSettings(password="not-the-password"))
    assert "Login failed: wrong user or password" in str(err.value)
    assert "\n" not in str(err.value)
    assert "not-the-password" not in str(err.value)
    assert not (tmp_path / "refused.mcap").exists()
