"""The whole emulated rig, read and driven through its three real transports."""

import time

import numpy as np

from hilrig.drivers.ft.gravity import gravity_wrench
from hilrig.drivers.ft.wire import FtSample
from hilrig.drivers.robot_state.wire import RobotState, RobotStatus
from hilrig.emulator.probe import RigProbe
from hilrig.emulator.rig import HOME_Q_RAD, EmulatedRig, RigConfig
from hilrig.errors import HilrigError
from hilrig.paper.profiles import end_effector_force, joint_torque
from hilrig.robot import RobotModel
from hilrig.world.scenarios import HandContact, PaperBody, PaperEndEffector, scenario


def read_at_least(probe: RigProbe, samples: int, states: int) -> tuple[list, list]:
    """At least ``samples`` F/T samples and ``states`` joint states (generous deadline)."""
    got_samples: list[FtSample] = []
    got_states: list[RobotState] = []
    deadline = time.monotonic() + 30.0
    while len(got_samples) < samples or len(got_states) < states:
        assert time.monotonic() < deadline, "too few frames"
        new_samples, new_states = probe.read(0.01)
        got_samples += new_samples
        got_states += new_states
    return got_samples, got_states


class Constant:
    """A volunteer pressing with a constant wrench on the sensor."""

    name = "constant"

    def __init__(self, wrench: list[float]) -> None:
        self.wrench = tuple(wrench)

    def wrench_in_sensor(self, t_s: float, pose: np.ndarray) -> tuple[float, ...]:
        return self.wrench

    def joint_torque(self, t_s: float) -> tuple[float, ...]:
        return (1.0, -2.0, 0.0, 0.0, 0.0, 0.0)


def test_rig_streams_sensor_and_state_and_follows_modbus_targets() -> None:
    rig = EmulatedRig(Constant([2.0, -1.0, 3.0, 0.0, 0.1, 0.0]))
    with rig as endpoints, RigProbe(endpoints) as probe:
        samples, states = read_at_least(probe, 300, 1)
        np.testing.assert_allclose(states[0].q_rad, HOME_Q_RAD, atol=1e-9)
        assert RobotStatus.HOLDING in states[0].status
        # the sensor reads the volunteer's wrench + bias + the tool's gravity at the home pose
        mean = np.mean([s.wrench_in_sensor for s in samples], axis=0)
        pose = RobotModel().fk(np.asarray(HOME_Q_RAD))
        config = RigConfig().ft
        expected = (
            np.array([2.0, -1.0, 3.0, 0.0, 0.1, 0.0])
            + np.asarray(config.bias_in_sensor)
            + gravity_wrench(config.tool, pose[:3, :3])
        )
        np.testing.assert_allclose(mean, expected, atol=0.02)
        # joint targets over Modbus move the arm; the watchdog count keeps it tracking
        target = np.asarray(HOME_Q_RAD) + 0.05
        for n in range(1, 401):
            assert not probe.write(target, n).isError()
            _, states = read_at_least(probe, 0, 1)  # one write per joint-state frame
        moved = states[-1]
        assert RobotStatus.TRACKING in moved.status
        np.testing.assert_allclose(moved.q_rad, target, atol=0.01)
        assert abs(moved.torque_nm[1] + 2.0) < 0.5  # measured joint torque, with noise
    assert rig.counters().modbus_writes == 400


def test_writes_sent_without_waiting_are_each_applied_and_acknowledged_in_order() -> None:
    rig = EmulatedRig(Constant([0.0] * 6))
    target = np.asarray(HOME_Q_RAD) - 0.03
    acks = []
    with rig as endpoints, RigProbe(endpoints) as probe:
        read_at_least(probe, 1, 1)
        for n in range(1, 301):  # a session's traffic: woken by the sensor, one write a frame
            probe.wait_for_ft(0.05)
            _, states = probe.read()
            acks += probe.acks()
            probe.send(target, n)
        deadline = time.monotonic() + 30.0
        while len(acks) < 300:
            assert time.monotonic() < deadline, f"{len(acks)} of 300 writes acknowledged"
            acks += probe.acks()
            _, states = probe.read(0.01)
        _, states = read_at_least(probe, 0, 1)
    assert [a.function_code for a in acks] == [0x10] * 300
    assert rig.counters().modbus_writes == 300
    np.testing.assert_allclose(states[-1].q_rad, target, atol=0.01)


def test_paper_scenarios_are_the_paper_profiles() -> None:
    pose = np.eye(4)
    for t_s in (3.9, 4.2, 4.5, 5.0, 5.7, 6.1):
        np.testing.assert_array_equal(
            PaperEndEffector().wrench_in_sensor(t_s, pose)[:3], end_effector_force(t_s)[0]
        )
        np.testing.assert_array_equal(PaperBody().joint_torque(t_s), joint_torque(t_s)[0])
    repeated = PaperEndEffector(period_s=10.0)
    assert repeated.wrench_in_sensor(14.5, pose)[0] == end_effector_force(4.5)[0, 0]


def test_hand_contact_closes_the_loop_through_the_robots_yielding() -> None:
    hand = HandContact(period_s=None, damping_n_s_m=0.0)
    still = np.eye(4)
    # t = 2.5 s: the hand has moved 0.05 m from 0.05 m short, so it just touches: no force yet
    assert not any(hand.wrench_in_sensor(2.5, still))
    # t = 2.7 s: 0.02 m past the tool's start; a tool that stayed put is pushed with k*0.02 N
    pushed = hand.wrench_in_sensor(2.7, still)
    np.testing.assert_allclose(pushed[:3], [0.0, 300.0 * 0.02, 0.0], atol=1e-9)
    # the moment of that force about the sensor origin, applied 0.1 m down the sensor's z
    np.testing.assert_allclose(pushed[3:], np.cross([0.0, 0.0, 0.1], pushed[:3]), atol=1e-12)
    # a tool that yielded 0.015 m along the push is pushed with only k*0.005 N
    yielded = np.eye(4)
    yielded[1, 3] = 0.015
    np.testing.assert_allclose(hand.wrench_in_sensor(2.7, yielded)[1], 300.0 * 0.005, atol=1e-9)
    # a hand never pulls: a tool that yielded beyond the hand gets no force
    yielded[1, 3] = 0.05
    assert not any(hand.wrench_in_sensor(2.7, yielded))


def test_unknown_scenario_is_refused() -> None:
    try:
        scenario("shove")
    except HilrigError as err:
        assert str(err) == (
            "unknown scenario 'shove'; known: hand-contact, none, paper-body, paper-end-effector"
        )
    else:
        raise AssertionError("no error")
