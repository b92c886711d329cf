"""AUBO's own client (pyaubo-sdk 0.24.1) against the emulated ARCS controller in a rig process.

The client's blocking calls hold the GIL, so the rig runs in its own process (RigProcess). Waits
poll a condition with a generous deadline; nothing asserts a time or a rate.
"""

import itertools
import math
import re
import time
from collections.abc import Callable, Iterator
from typing import Any

import pyaubo_sdk as aubo
import pytest

from hilrig.emulator.arcs import ArcsConfig
from hilrig.emulator.rig import HOME_Q_RAD, RigConfig, RigEndpoints
from hilrig.rig.rig_process import RigProcess

DEADLINE_S = 30.0
WRONG_LOGIN = "getRobotNames-getRobotNames--32000: Login failed: wrong user or password"
TOPIC = ["timestamp", "R1_actual_q", "R1_actual_current", "R1_robot_mode", "R1_safety_mode"]


def wait_for(condition: Callable[[], bool]) -> None:
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.01)


@pytest.fixture(scope="module")
def rig() -> Iterator[tuple[RigProcess, RigEndpoints]]:
    # no joint noise and the volunteer's clock held at 0: a holding arm's values are constant
    config = RigConfig(
        joint_torque_noise_nm=0.0,
        scenario_starts_at_open=False,
        arcs=ArcsConfig(servo_timeout_s=0.5),
    )
    process = RigProcess("paper-end-effector", config=config)
    endpoints = process.start()
    yield process, endpoints
    process.stop()


@pytest.fixture
def rpc(rig: tuple[RigProcess, RigEndpoints]) -> Iterator[Any]:
    process, endpoints = rig
    process.fault("arcs.reset")
    client = aubo.RpcClient()
    client.setRequestTimeout(5000)
    assert client.connect(*endpoints.aubo_rpc) == 0
    assert client.login("aubo", "123456") == 0
    state = client.getRobotInterface("rob1").getRobotState()
    wait_for(lambda: state.getSafetyModeType() == aubo.SafetyModeType.Normal)
    yield client
    client.disconnect()


class Samples:
    """An RTDE client subscribed to ``names`` at ``frequency_hz``; ``rows`` as received."""

    def __init__(self, endpoints: RigEndpoints, names: list[str], frequency_hz: float) -> None:
        self.client = aubo.RtdeClient()
        assert self.client.connect(*endpoints.aubo_rtde) == 0
        assert self.client.login("aubo", "123456") == 0
        wait_for(lambda: bool(self.client.getOutputMaps()))  # the hello is in
        self.names = names
        self.rows: list[list[Any]] = []
        self.topic = self.client.setTopic(False, names, frequency_hz, 0)
        assert self.topic == 0
        assert self.client.subscribe(self.topic, self._take) == 0

    def _take(self, parser: Any) -> None:
        row: list[Any] = []
        for name in self.names:
            if name == "timestamp":
                row.append(parser.popDouble())
            elif name == "R1_robot_mode":
                row.append(parser.popRobotModeType())
            elif name == "R1_safety_mode":
                row.append(parser.popSafetyModeType())
            else:
                row.append(parser.popVectorDouble())
        self.rows.append(row)

    def wait_more(self, count: int) -> list[list[Any]]:
        start = len(self.rows)
        wait_for(lambda: len(self.rows) >= start + count)
        return self.rows[start:]

    def close(self) -> None:
        self.client.disconnect()


def slot_index(timestamp_s: float) -> int:
    return round(timestamp_s * 1000)  # 1 ms slots since the controller started


def robot(client: Any) -> tuple[Any, Any]:
    interface = client.getRobotInterface("rob1")
    return interface.getMotionControl(), interface.getRobotState()


def test_connect_login_and_robot_names(rpc: Any) -> None:
    assert rpc.hasConnected() and rpc.hasLogined()
    assert rpc.getRobotNames() == ["rob1"]
    _, state = robot(rpc)
    assert state.getRobotModeType() == aubo.RobotModeType.Running
    assert state.getJointPositions() == pytest.approx(list(HOME_Q_RAD), abs=0.2)


def test_servo_joint_moves_the_arm_to_the_command(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any
) -> None:
    process, _ = rig
    motion, state = robot(rpc)
    assert motion.servoJoint(list(HOME_Q_RAD), 0.1, 0.2, 0.005, 0.1, 200) == -13  # not servo
    assert motion.setServoMode(True) == 0
    assert motion.isServoModeEnabled() is True
    q0 = state.getJointPositions()
    target = [q0[0] + 0.05, q0[1] - 0.05, q0[2] + 0.05, q0[3], q0[4], q0[5]]
    before = process.counters().servo_joints
    accepted = 0
    deadline = time.monotonic() + DEADLINE_S
    while max(abs(a - b) for a, b in zip(state.getJointPositions(), target, strict=True)) > 1e-6:
        assert time.monotonic() < deadline, "the arm did not reach the command"
        code = motion.servoJoint(target, 0.1, 0.2, 0.005, 0.1, 200)
        if code == -13:  # the client was too slow for the servo timeout: servo mode again
            assert motion.setServoMode(True) == 0
            continue
        assert code == 0
        accepted += 1
        time.sleep(0.002)
    assert process.counters().servo_joints - before == accepted
    assert state.getJointPositions() == pytest.approx(target, abs=1e-6)
    assert motion.servoJoint([0.0] * 5, 0.1, 0.2, 0.005, 0.1, 200) == -5
    assert motion.servoJoint([math.nan] * 6, 0.1, 0.2, 0.005, 0.1, 200) == -5
    assert motion.setServoMode(False) == 0
    assert motion.isServoModeEnabled() is False


def test_rpc_and_rtde_agree_while_the_arm_holds(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any
) -> None:
    _, endpoints = rig
    _, state = robot(rpc)
    names = ["timestamp", "R1_actual_q", "R1_joint_torque_sensor", "R1_actual_current"]
    samples = Samples(endpoints, names, 200.0)
    try:
        # holding: wait until two samples in a row carry the same positions
        wait_for(lambda: len(samples.rows) >= 2 and samples.rows[-1][1] == samples.rows[-2][1])
        q, torque, current = (
            state.getJointPositions(),
            state.getJointTorqueSensors(),
            state.getJointCurrents(),
        )
        _, q_rtde, torque_rtde, current_rtde = samples.wait_more(1)[-1]
    finally:
        samples.close()
    assert q == q_rtde and torque == torque_rtde and current == current_rtde
    assert len(q) == len(torque) == len(current) == 6


@pytest.mark.parametrize("frequency_hz", [200.0, 500.0])
def test_rtde_topic_sends_every_sample_in_order(
    rig: tuple[RigProcess, RigEndpoints], frequency_hz: float
) -> None:
    process, endpoints = rig
    skipped_before = process.counters().slots_skipped
    samples = Samples(endpoints, TOPIC, frequency_hz)
    try:
        rows = samples.wait_more(100)
        assert samples.client.removeTopic(False, samples.topic) == 0
    finally:
        samples.close()
    skipped = process.counters().slots_skipped - skipped_before
    steps = [slot_index(b[0]) - slot_index(a[0]) for a, b in itertools.pairwise(rows)]
    period_slots = round(1000 / frequency_hz)
    if skipped == 0:
        assert set(steps) == {period_slots}
    else:  # a slot the loop skipped is a sample not sent: gaps, never disorder (the next sample
        # goes out at the first slot run after the skip, which may lie off the period's grid)
        assert all(step > 0 for step in steps)
        index = [slot_index(row[0]) * round(frequency_hz) // 1000 for row in rows]
        assert all(b > a for a, b in itertools.pairwise(index))
    assert all(len(row[1]) == len(row[2]) == 6 for row in rows)
    assert {row[3] for row in rows} == {aubo.RobotModeType.Running}
    assert {row[4] for row in rows} == {aubo.SafetyModeType.Normal}


def test_wrong_password_and_unknown_method(rig: tuple[RigProcess, RigEndpoints], rpc: Any) -> None:
    _, endpoints = rig
    wrong = aubo.RpcClient()
    wrong.setRequestTimeout(5000)
    assert wrong.connect(*endpoints.aubo_rpc) == 0
    with pytest.raises(aubo.AuboException, match=re.escape(WRONG_LOGIN)):
        wrong.login("aubo", "wrong")
    motion, _ = robot(rpc)
    with pytest.raises(
        aubo.AuboException, match=re.escape("rob1.MotionControl.moveJoint--32601: Method not found")
    ):
        motion.moveJoint(list(HOME_Q_RAD), 1.0, 1.0, 0.0, 0.0)


def test_refused_login_fails_once_as_a_wrong_password(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any
) -> None:
    process, endpoints = rig
    process.fault("arcs.refuse_login", 1)
    refused, accepted = aubo.RpcClient(), aubo.RpcClient()
    for client in (refused, accepted):
        client.setRequestTimeout(5000)
        assert client.connect(*endpoints.aubo_rpc) == 0
    with pytest.raises(aubo.AuboException, match=re.escape(WRONG_LOGIN)):
        refused.login("aubo", "123456")
    assert accepted.login("aubo", "123456") == 0
    assert accepted.getRobotNames() == ["rob1"]
    accepted.disconnect()


@pytest.mark.parametrize(
    ("fault", "safety", "mode"),
    [
        ("arcs.protective_stop", aubo.SafetyModeType.ProtectiveStop, aubo.RobotModeType.Running),
        ("arcs.emergency_stop", aubo.SafetyModeType.RobotEmergencyStop, aubo.RobotModeType.Idle),
    ],
)
def test_a_stop_refuses_servo_joint(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any, fault: str, safety: Any, mode: Any
) -> None:
    process, endpoints = rig
    motion, state = robot(rpc)
    assert motion.setServoMode(True) == 0
    samples = Samples(endpoints, TOPIC, 500.0)
    try:
        process.fault(fault)
        wait_for(lambda: state.getSafetyModeType() == safety)
        wait_for(lambda: bool(samples.rows) and samples.rows[-1][4] == safety)
        assert samples.rows[-1][3] == mode
    finally:
        samples.close()
    assert state.getRobotModeType() == mode
    assert motion.isServoModeEnabled() is False
    assert motion.servoJoint(list(HOME_Q_RAD), 0.1, 0.2, 0.005, 0.1, 200) == 1
    assert motion.setServoMode(True) == 1


def test_servo_timeout_fault_and_real_timeout(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any
) -> None:
    process, _ = rig
    motion, _ = robot(rpc)
    assert motion.setServoMode(True) == 0
    process.fault("arcs.servo_timeout")
    wait_for(lambda: motion.isServoModeEnabled() is False)
    assert motion.servoJoint(list(HOME_Q_RAD), 0.1, 0.2, 0.005, 0.1, 200) == -13
    assert motion.setServoMode(True) == 0  # no servoJoint follows: it ends by itself
    wait_for(lambda: motion.isServoModeEnabled() is False)


def test_stall_rtde_leaves_a_gap_of_its_length(rig: tuple[RigProcess, RigEndpoints]) -> None:
    process, endpoints = rig
    samples = Samples(endpoints, ["timestamp"], 500.0)
    try:
        samples.wait_more(5)
        process.fault("arcs.stall_rtde", 0.2)
        samples.wait_more(150)
    finally:
        samples.close()
    steps = [slot_index(b[0]) - slot_index(a[0]) for a, b in itertools.pairwise(samples.rows)]
    assert max(steps) >= 200  # no sample in the 200 slots of the stall
    assert all(step > 0 for step in steps)


def test_drop_links_disconnects_both_clients(
    rig: tuple[RigProcess, RigEndpoints], rpc: Any
) -> None:
    process, endpoints = rig
    samples = Samples(endpoints, ["timestamp"], 200.0)
    try:
        samples.wait_more(2)
        process.fault("arcs.drop_links")
        wait_for(lambda: not samples.client.hasConnected())
    finally:
        samples.close()
    wait_for(lambda: not rpc.hasConnected())  # the client's reader saw the link close
    _, state = robot(rpc)
    with pytest.raises(aubo.AuboException, match=re.escape("RPC client has not connected")):
        state.getJointPositions()
