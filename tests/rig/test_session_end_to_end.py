"""Recorded emulated sessions, end to end, checked through the recording itself."""

import json
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from hilrig.control import combine, preset, simulate
from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import HilrigError
from hilrig.machine import read_settings
from hilrig.recording import inspect, load, recover
from hilrig.recording.samples import EventKind
from hilrig.rig import (
    ControlLoop,
    RecorderProcess,
    RigProcess,
    SessionConfig,
    SessionResult,
    record_session,
)
from hilrig.rig.kinds import RobotLinkKind
from hilrig.rig.session_config import machine_json

TOPICS_AT_1KHZ = (
    "/ft/wrist",
    "/joint_states",
    "/controller/input",
    "/controller/state",
    "/trajectory/desired",
    "/trajectory/commanded",
    "/diagnostics/loop",
)


def run(
    tmp: Path,
    name: str,
    seconds: float,
    *,
    scenario: str = "paper-end-effector",
    during: Callable[[RigProcess, ControlLoop, threading.Event], None] | None = None,
    recorders: list[RecorderProcess] | None = None,
    robot_link: RobotLinkKind = RobotLinkKind.ARCS,
) -> SessionResult:
    """Record a session; ``during`` runs in a thread once the loop has started."""
    rig_box: list[RigProcess] = []
    stop = threading.Event()

    def on_start(loop: ControlLoop) -> None:
        if during is not None:
            threading.Thread(target=during, args=(rig_box[0], loop, stop), daemon=True).start()

    return record_session(
        SessionConfig(
            out=tmp / name,
            subject_id="S001",
            scenario=scenario,
            duration_s=seconds,
            robot_link=robot_link,
        ),
        stop=stop,
        on_start=on_start,
        rig_ready=rig_box.append,
        recorder_ready=None if recorders is None else recorders.append,
    )


@pytest.fixture(scope="module")
def collision(tmp_path_factory: pytest.TempPathFactory) -> SessionResult:
    """The paper's end-effector collision (4 s to 6 s) in a 6.5 s session."""
    return run(tmp_path_factory.mktemp("session"), "collision.mcap", 6.5)


def test_every_frame_the_rig_sent_and_every_tick_is_recorded(collision: SessionResult) -> None:
    frames = load(collision.path)
    counters = collision.rig_counters
    assert counters is not None
    # every frame the rig sent is recorded or counted as dropped (on an idle machine: none is);
    # hold ticks are not asserted: a loaded machine may cause some
    ft, joints = frames["/ft/wrist"], frames["/joint_states"]
    assert counters.ft_frames_dropped == 0
    assert 0 < len(ft) <= counters.ft_frames_sent <= len(ft) + collision.drops
    # the joint states came over RTDE (the ARCS link, the default)
    assert 0 < len(joints) <= counters.rtde_samples_sent <= len(joints) + collision.drops
    if collision.drops == 0:
        assert (len(ft), len(joints)) == (counters.ft_frames_sent, counters.rtde_samples_sent)
    ticks = frames["/diagnostics/loop"]
    logged = ticks["tick"].to_numpy()
    assert np.all(np.diff(logged) >= 1) and len(logged) + collision.drops >= collision.summary.ticks
    for topic in TOPICS_AT_1KHZ:
        t_ns = frames[topic].index.to_numpy()
        assert np.all(np.diff(t_ns) >= 0), topic
        if topic not in ("/ft/wrist", "/joint_states"):
            assert len(t_ns) == len(ticks), topic  # one message a logged tick
    # every frame the sensor sent triggered a tick, unless it came after the session's end
    assert collision.summary.ticks <= counters.ft_frames_sent


def test_recorded_state_is_the_controller_replayed_on_the_recorded_input(
    collision: SessionResult,
) -> None:
    state = load(collision.path, topics=["/controller/state"])["/controller/state"]
    force = state[[f"force_{i}" for i in range(9)]].to_numpy()
    offset = state[[f"offset_{i}" for i in range(9)]].to_numpy()
    params = combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6))
    replayed = simulate("adaptive", force, 0.001, params)
    # the controller steps on every tick (on the last fresh input during a hold), so this
    # holds whatever the session went through
    np.testing.assert_allclose(replayed.offset, offset, rtol=0, atol=1e-12)


def test_the_collision_moves_the_robot_and_is_logged(collision: SessionResult) -> None:
    kinds = [e.kind for e in collision.events]
    assert EventKind.COLLISION_START in kinds and EventKind.COLLISION_END in kinds
    state = load(collision.path, topics=["/controller/state"])["/controller/state"]
    assert np.abs(state["offset_0"]).max() > 0.005  # the end effector yielded by > 5 mm in x


def test_faults_hold_the_robot_and_are_logged_while_the_loop_keeps_ticking(
    tmp_path: Path,
) -> None:
    def inject(rig: RigProcess, loop: ControlLoop, stop: threading.Event) -> None:
        for fault, args, at_s in (
            ("ft.stall", (0.1,), 0.5),
            ("robot_state.stall", (0.1,), 1.0),
            ("modbus.inject_exceptions", (1,), 1.5),
            ("robot_state.drop_links", (0.1,), 2.0),
        ):
            while loop.summary.ticks < at_s * 1000:  # session time, however long warm-up took
                time.sleep(0.001)
            rig.fault(fault, *args)
        # the session ends half a second after the robot's link is back and tracking resumed,
        # however long its reconnection took on a loaded machine (its backoff grows)
        while loop.summary.ticks < 2200 or loop.holding:
            time.sleep(0.001)
        resumed = loop.summary.ticks
        while loop.summary.ticks < resumed + 500:
            time.sleep(0.001)
        stop.set()

    # the Modbus pair's faults (the ARCS link's: tests/rig/arcs/test_arcs_sessions.py)
    result = run(
        tmp_path,
        "faults.mcap",
        60.0,
        scenario="paper-body",
        during=inject,
        robot_link=RobotLinkKind.MODBUS,
    )
    faults = [e for e in result.events if e.kind == EventKind.FAULT]
    sources = [e.source for e in faults]
    assert "wrist F/T sensor" in sources
    assert sources.count("robot joint state") >= 4  # stale and back, twice (stall, dropped link)
    assert "joint targets" in sources
    assert result.summary.hold_ticks >= 50
    # the loop kept ticking through every fault: ticks are logged after the last fault's time
    ticks = load(result.path, topics=["/diagnostics/loop"])["/diagnostics/loop"]
    assert ticks.index.to_numpy()[-1] > max(e.t_ns for e in faults)
    np.testing.assert_array_equal(ticks["tick"].to_numpy(), np.arange(1, len(ticks) + 1))
    # tracking resumed after the dropped link: the last fault is a recovery
    last_robot = [e for e in faults if e.source == "robot joint state"][-1]
    assert last_robot.detail.startswith("data fresh again")
    recorded = load(result.path, topics=["/events"])["/events"]
    assert len(recorded) == len(result.events)


def test_a_killed_recorder_ends_the_session_at_once_and_loses_at_most_half_a_second(
    tmp_path: Path,
) -> None:
    recorders: list[RecorderProcess] = []
    ticks_at_kill: list[int] = []

    def kill(rig: RigProcess, loop: ControlLoop, stop: threading.Event) -> None:
        while loop.summary.ticks < 1000:  # 1 s into the session, however long warm-up took
            time.sleep(0.001)
        ticks_at_kill.append(loop.summary.ticks)
        pid = recorders[0].pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)

    result = run(tmp_path, "killed.mcap", 30.0, during=kill, recorders=recorders)
    assert result.messages_written is None
    assert result.recorder_error.startswith(f"recorder of {result.path}: exited with code -9")
    # the recorder's end woke the loop (its sentinel): it ended within the kill's own delay,
    # far from the 30 s asked for, and said why
    assert result.summary.ticks < 10_000
    assert result.summary.ticks - ticks_at_kill[0] <= 1000
    ended = [e for e in result.events if e.source == "session"]
    assert ended and ended[-1].detail == "the recorder process died: robot held, session ended"
    assert result.ended_by == "the recorder process died"
    recover(result.path, tmp_path / "recovered.mcap")
    diagnostics = load(tmp_path / "recovered.mcap", topics=["/diagnostics/loop"])
    last_tick = int(diagnostics["/diagnostics/loop"]["tick"].to_numpy()[-1])
    lost_s = (ticks_at_kill[0] - last_tick) / 1000
    assert 0 <= lost_s <= 0.5


def test_the_collision_starts_on_time_counted_from_the_first_tick(
    collision: SessionResult,
) -> None:
    # the scenario's clock starts with the session (RigProcess.start_scenario), however long
    # start-up took: eq. 15-17 rise from 0 at 4.0 s, |f| passes 0.5 N about 40 ms later
    state = load(collision.path, topics=["/controller/state"])["/controller/state"]
    t_s = (state.index.to_numpy() - state.index.to_numpy()[0]) / 1e9
    force = np.linalg.norm(state[["force_0", "force_1", "force_2"]].to_numpy(), axis=1)
    pushed = force > 0.5
    onset_s = t_s[np.argmax(pushed)]
    assert 3.95 <= onset_s <= 4.25
    assert not pushed[t_s < onset_s].any()


def test_the_file_ends_with_the_loop_s_figures(collision: SessionResult) -> None:
    outcome = inspect(collision.path).outcome
    summary = collision.summary
    assert outcome is not None
    assert (outcome.ticks, outcome.hold_ticks, outcome.fallback_ticks) == (
        summary.ticks,
        summary.hold_ticks,
        summary.fallback_ticks,
    )
    assert outcome.missed_deadlines == summary.missed_deadlines
    assert (outcome.recorder_drops, outcome.ended_by) == (collision.drops, "duration reached")


def test_no_folder_of_the_output_is_stored_in_the_file(collision: SessionResult) -> None:
    from mcap.reader import make_reader

    folder = str(collision.path.parent).encode()
    home = os.path.expanduser("~").encode()
    with collision.path.open("rb") as stream:
        reader = make_reader(stream)
        texts = [
            *(f"{m.name}={m.metadata}".encode() for m in reader.iter_metadata()),
            *(a.name.encode() + a.data for a in reader.iter_attachments()),
        ]
    assert texts and not [t for t in texts if folder in t or home + b"/" in t]
    assert folder not in collision.path.read_bytes()


def test_the_machine_s_settings_are_attached_as_doctor_reads_them(
    collision: SessionResult,
) -> None:
    from mcap.reader import make_reader

    with collision.path.open("rb") as stream:
        attached = {a.name: a for a in make_reader(stream).iter_attachments()}
    machine = attached["machine.json"]
    assert machine.media_type == "application/json"
    settings = json.loads(machine.data)
    now = [asdict(s) for s in read_settings()]
    assert [s["name"] for s in settings] == [s["name"] for s in now]
    realtime = [s for s in settings if s["name"] == "real-time scheduling"]
    assert realtime == [s for s in now if s["name"] == "real-time scheduling"]


def test_a_real_rig_s_machine_settings_name_its_sensor_port_by_its_file_name(
    tmp_path: Path,
) -> None:
    parent, child = os.openpty()
    try:
        port = os.ttyname(child)
        config = SessionConfig(
            out=tmp_path / "s.mcap",
            subject_id="S001",
            rig="aubo",
            endpoints=RigEndpoints(port, ("127.0.0.1", 8002), ("127.0.0.1", 502)),
        )
        settings = json.loads(machine_json(config.machine_settings()))
    finally:
        os.close(parent)
        os.close(child)
    assert [s["name"] for s in settings][-3:] == ["F/T port", "F/T port access", "F/T port driver"]
    assert settings[-3]["value"] == Path(port).name
    emulated = SessionConfig(out=tmp_path / "e.mcap", subject_id="S001")
    names = [s["name"] for s in json.loads(machine_json(emulated.machine_settings()))]
    assert not [name for name in names if name.startswith("F/T port")]


def test_a_virtual_collision_s_source_keeps_only_its_file_name(tmp_path: Path) -> None:
    config = SessionConfig(
        out=tmp_path / "jane.doe" / "replayed.mcap",
        subject_id="S001",
        virtual_source=f"{tmp_path}/jane.doe/session.mcap from 2.0 s for 3.000 s",
    )
    assert '"virtual_source": "session.mcap from 2.0 s for 3.000 s"' in config.as_json()
    assert '"out": "replayed.mcap"' in config.as_json()
    assert "jane.doe" not in config.as_json()


def test_a_session_that_cannot_start_leaves_nothing(tmp_path: Path) -> None:
    def fail(rig: RigProcess) -> None:
        raise HilrigError("the rig is not ready")

    out = tmp_path / "new" / "folder" / "s.mcap"
    with pytest.raises(HilrigError, match=r"^the rig is not ready$"):
        record_session(SessionConfig(out=out, subject_id="S001", duration_s=2.0), rig_ready=fail)
    assert not list(tmp_path.iterdir())  # not the file, nor the folders made for it


def test_a_session_that_fails_once_recording_keeps_its_file_and_says_where(
    tmp_path: Path,
) -> None:
    def fail(loop: ControlLoop) -> None:
        raise HilrigError("the operator's screen is gone")

    out = tmp_path / "s.mcap"
    with pytest.raises(HilrigError) as caught:
        record_session(SessionConfig(out=out, subject_id="S001", duration_s=2.0), on_start=fail)
    assert caught.value.__notes__ == [f"what was recorded until then is in {out}"]
    assert inspect(out).complete  # closed cleanly, with the start-up's samples
    assert len(load(out, topics=["/joint_states"])["/joint_states"]) > 0


def test_a_wrist_sensor_silent_from_the_start_holds_and_the_session_still_ends(
    tmp_path: Path,
) -> None:
    # the sensor's link is cut once the file is open, before the first tick (what was buffered
    # goes with it): no frame triggers a tick, so every tick is a fallback tick on the deadline
    rigs: list[RigProcess] = []
    results: list[SessionResult] = []
    stop = threading.Event()

    def silence(_: RecorderProcess) -> None:
        rigs[0].fault("ft.drop_link", 30.0)
        time.sleep(0.1)  # applied at the rig's next slot

    def record() -> None:
        config = SessionConfig(out=tmp_path / "silent.mcap", subject_id="S001", duration_s=1.0)
        results.append(
            record_session(config, stop=stop, rig_ready=rigs.append, recorder_ready=silence)
        )

    session = threading.Thread(target=record, daemon=True)
    session.start()
    session.join(900.0)  # it used to wait for a first frame forever (900 s: other sessions)
    stop.set()
    session.join(30.0)
    assert results, "the session did not end on its own"
    summary = results[0].summary
    assert summary.ticks > 0
    assert summary.fallback_ticks == summary.ticks  # not one tick was triggered by a frame
    assert summary.ticks <= 1000  # it ended at its duration: no tick beyond 1 s of the grid
    assert summary.hold_ticks >= summary.ticks - 5  # stale after 5 ticks (the tare's samples)
    stale = [e for e in results[0].events if e.source == "wrist F/T sensor"]
    assert stale and stale[0].detail.startswith("stale or lost")
    ticks = load(results[0].path, topics=["/diagnostics/loop"])["/diagnostics/loop"]
    assert len(ticks) == summary.ticks
