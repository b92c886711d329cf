"""The compiled tick against the reference path it replaced, and its limits property.

The reference is the tick as the loop did it in Python before: pinocchio forward and inverse
kinematics (``RobotModel``), ``GravityCompensator.compensate``, ``SafetyClamp.clamp``/``hold``/
``stop_required`` and ``AdmittanceController.step``. Both run side by side on the same inputs,
from a recorded session and from hypothesis, and must agree to 1e-12 on every tick.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from hilrig.drivers.ft.gravity import GravityCompensator, ToolLoad
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.recording import load
from hilrig.rig.loop import LoopConfig
from hilrig.rig.records import TICK_DTYPE
from hilrig.ring_kernels import DROPPED_AT, READ_AT, READ_SEEN_AT, WRITE_AT
from hilrig.robot import RobotModel
from hilrig.tick.clamp_kernels import HOLDING
from hilrig.tick.kernel import (
    COMMAND_OK,
    CONTACT_CHANGED,
    FRESH,
    HELD,
    ROBOT_OK,
    SENSOR_OK,
    STOP_NOW,
    CompiledTick,
)
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.trajectory import make_trajectory

MODEL = RobotModel()
EXAMPLE = Path(__file__).parents[2] / "recordings" / "example-paper-end-effector.mcap"
TOOL = ToolLoad(mass_kg=0.5, com_in_sensor_m=(0.0, 0.0, 0.05))
Vec = NDArray[np.float64]


@dataclass
class Reference:
    """The tick as the loop computed it in Python, one call per device, model and clamp."""

    compensator: GravityCompensator
    clamp: SafetyClamp
    q0: Vec

    def __post_init__(self) -> None:
        self.controller = LoopConfig().controller()
        self.q_ik = self.q0.copy()
        self.q_cmd = self.q0.copy()
        self.force = np.zeros(9)
        self.stopped = False
        self.contact = (0, 0)  # the axis groups' contact codes (end effector, joints): free

    def tick(
        self, flags_in: int, raw: Vec, q: Vec, tau: Vec, extra: Vec, position: Vec, rotation: Vec
    ) -> int:
        fresh = bool(flags_in & SENSOR_OK) and bool(flags_in & ROBOT_OK)
        result = 0
        stop_now = False
        if fresh:
            r_base_sensor = MODEL.fk(q)[:3, :3]
            wrench = self.compensator.compensate(raw, r_base_sensor)
            with np.errstate(invalid="ignore", over="ignore"):  # non-finite inputs: not fresh
                fresh9 = np.concatenate([r_base_sensor @ wrench[:3], tau]) + extra
            fresh = bool(np.isfinite(fresh9).all() and np.isfinite(wrench).all())
        if fresh:
            result |= FRESH
            self.force[:] = fresh9
            if not self.stopped and self.clamp.stop_required(self.force[:3], self.force[3:]):
                self.stopped = stop_now = True
        offsets = self.controller.step(self.force)
        if not (fresh and flags_in & COMMAND_OK) or self.stopped:
            flags = self.clamp.hold(self.q_cmd) | HELD
        else:
            x_r = np.eye(4)
            x_r[:3, 3] = position + offsets[:3]
            x_r[:3, :3] = rotation
            ik = MODEL.ik(
                x_r, self.q_ik, max_iterations=2, tol_position_m=1e-8, tol_rotation_rad=1e-8
            )
            self.q_ik[:] = ik.q_rad
            flags = self.clamp.clamp(self.q_ik + offsets[3:], self.q_cmd)
        contact = (int(self.controller.contact[0]), int(self.controller.contact[3]))
        changed = CONTACT_CHANGED if contact != self.contact else 0
        self.contact = contact
        return result | flags | (STOP_NOW if stop_now else 0) | changed


def pair(q0: Vec, compensator: GravityCompensator) -> tuple[Reference, CompiledTick]:
    config = SafetyConfig()
    reference = Reference(compensator, SafetyClamp(config, MODEL, q0), q0)
    compiled = CompiledTick.build(
        LoopConfig().controller(), MODEL, SafetyClamp(config, MODEL, q0), compensator, q0, 1e-3
    )
    return reference, compiled


def agree(reference: Reference, compiled: CompiledTick, ref_flags: int, flags: int) -> None:
    """Same flags; values within 1e-12 (absolute, or relative for values above 1: the two paths
    sum the 3x3 rotation's products in different orders)."""
    assert flags == ref_flags
    np.testing.assert_allclose(compiled.q_cmd, reference.q_cmd, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(compiled.force, reference.force, rtol=1e-12, atol=1e-12)
    offset = compiled.arrays.offset
    np.testing.assert_allclose(offset, reference.controller.offset, rtol=1e-12, atol=1e-12)


def test_the_compiled_tick_reproduces_the_reference_on_a_recorded_session() -> None:
    streams = load(EXAMPLE, topics=["/ft/wrist", "/joint_states"])
    ft, joints = streams["/ft/wrist"], streams["/joint_states"]
    raw = ft[[f"wrench.{p}.{a}" for p in ("force", "torque") for a in "xyz"]].to_numpy()
    q_rec = joints[[f"position_{j}" for j in range(6)]].to_numpy()
    tau_rec = joints[[f"effort_{j}" for j in range(6)]].to_numpy()
    joint_of_ft = np.searchsorted(
        joints["publish_time_ns"].to_numpy(), ft["publish_time_ns"].to_numpy(), side="right"
    )
    q0 = q_rec[0]
    start = MODEL.fk(q0)
    compensator = GravityCompensator(TOOL)
    compensator.tare(raw[:100].mean(axis=0), start[:3, :3])
    reference, compiled = pair(q0, compensator)
    trajectory = make_trajectory("circle", start)
    position, extra = np.zeros(3), np.zeros(9)
    flags_in = SENSOR_OK | ROBOT_OK | COMMAND_OK
    ticks, largest_m, changes = 0, 0.0, 0
    for n in range(100, len(raw)):
        j = max(int(joint_of_ft[n]) - 1, 0)
        trajectory.desired(n * 2e-3, position)
        args = (flags_in, raw[n], q_rec[j], tau_rec[j], extra, position, trajectory.rotation)
        flags = compiled.run(*args)
        agree(reference, compiled, reference.tick(*args), flags)
        ticks += 1
        changes += bool(flags & CONTACT_CHANGED)
        largest_m = max(largest_m, float(np.abs(compiled.arrays.offset[:3]).max()))
    assert ticks == len(raw) - 100
    assert largest_m > 5e-3  # the recorded collision made the arm yield
    assert changes >= 2  # contact, then recovering (each tick that changed it is flagged)


finite = st.floats(-200, 200)
anything = st.floats(allow_nan=True, allow_infinity=True, width=64) | finite
tick_inputs = st.tuples(
    st.integers(0, 7),  # SENSOR_OK | ROBOT_OK | COMMAND_OK
    st.tuples(*[anything] * 6),  # raw wrench
    st.tuples(*[anything] * 6),  # joint torques
    st.tuples(*[finite] * 3),  # virtual input, x y z
)


@settings(max_examples=60, deadline=None)
@given(ticks=st.lists(tick_inputs, min_size=1, max_size=200))
def test_the_compiled_tick_reproduces_the_reference_on_any_input(
    ticks: list[tuple[int, tuple[float, ...], tuple[float, ...], tuple[float, ...]]],
) -> None:
    q0 = np.asarray(HOME_Q_RAD)
    start = MODEL.fk(q0)
    compensator = GravityCompensator(TOOL, bias_in_sensor=(0.5, -0.2, 1.0, 0.01, 0.0, -0.01))
    reference, compiled = pair(q0, compensator)
    trajectory = make_trajectory("circle", start)
    position = np.zeros(3)
    q = q0.copy()
    for n, (flags_in, raw, tau, virtual) in enumerate(ticks):
        trajectory.desired(n * 1e-3, position)
        extra = np.zeros(9)
        extra[:3] = virtual
        args = (flags_in, np.asarray(raw), q, np.asarray(tau), extra, position, start[:3, :3])
        agree(reference, compiled, reference.tick(*args), compiled.run(*args))
        q = compiled.q_cmd.copy()  # the robot follows its targets exactly


values = st.floats(allow_nan=True, allow_infinity=True, width=64) | st.floats(-500, 500)


@settings(max_examples=40, deadline=None)
@given(inputs=st.lists(st.tuples(*[values] * 12), min_size=1, max_size=300))
def test_commanded_targets_stay_inside_the_limits_whatever_the_input(
    inputs: list[tuple[float, ...]],
) -> None:
    q0 = np.asarray(HOME_Q_RAD)
    config = SafetyConfig()
    _, compiled = pair(q0, GravityCompensator())
    rotation = MODEL.fk(q0)[:3, :3]
    position = MODEL.fk(q0)[:3, 3].copy()
    q = q0.copy()
    sent = [q0, q0]
    for values_ in inputs:
        wrench, torque = np.asarray(values_[:6]), np.asarray(values_[6:])
        flags_in = SENSOR_OK | ROBOT_OK | COMMAND_OK
        compiled.run(flags_in, wrench, q, torque, np.zeros(9), position, rotation)
        q = compiled.q_cmd.copy()
        sent.append(q)
    commanded = np.array(sent)
    assert np.all(commanded >= config.lower_rad() - 1e-12)
    assert np.all(commanded <= config.upper_rad() + 1e-12)
    velocity = np.diff(commanded, axis=0) / 1e-3
    assert np.all(np.abs(velocity) <= np.array(config.limits.velocity_max_rad_s) + 1e-9)
    acceleration = np.diff(velocity, axis=0) / 1e-3
    assert np.all(np.abs(acceleration) <= np.array(config.limits.acceleration_max_rad_s2) + 1e-6)


def test_a_force_above_the_protective_limit_stops_and_holds_for_good() -> None:
    q0 = np.asarray(HOME_Q_RAD)
    _, compiled = pair(q0, GravityCompensator())
    pose = MODEL.fk(q0)
    flags_in = SENSOR_OK | ROBOT_OK | COMMAND_OK
    push = np.array([0.0, 0.0, 100.0, 0.0, 0.0, 0.0])  # 100 N > 60 N
    args = (np.zeros(6), np.zeros(9), pose[:3, 3].copy(), pose[:3, :3])
    first = compiled.run(flags_in, push, q0, *args)
    assert first & STOP_NOW and first & HELD and first & HOLDING
    later = compiled.run(flags_in, np.zeros(6), q0, *args)
    assert later & HELD and not later & STOP_NOW and compiled.stopped


def test_the_tick_row_holds_what_the_tick_computed() -> None:
    q0 = np.asarray(HOME_Q_RAD)
    _, compiled = pair(q0, GravityCompensator())
    pose = MODEL.fk(q0)
    wrench = np.array([2.0, -1.0, 0.5, 0.01, 0.02, 0.03])
    compiled.run(SENSOR_OK | ROBOT_OK | COMMAND_OK, wrench, q0, np.ones(6), np.zeros(9),
                 pose[:3, 3].copy(), pose[:3, :3])  # fmt: skip
    rows = np.zeros(3, dtype=TICK_DTYPE)
    header, other = np.zeros(24, dtype=np.int64), np.zeros(24, dtype=np.int64)
    header[WRITE_AT] = header[READ_AT] = header[READ_SEEN_AT] = 4  # empty, next slot 1
    header[DROPPED_AT], other[DROPPED_AT] = 20, 300
    k = compiled.arrays
    quaternion = np.array([0.0, 0.0, 0.0, 1.0])
    compiled.inputs.orientation_d[:] = quaternion
    put = compiled.row_writer(rows, header, (header, other))  # as the loop binds it
    assert put(1, 2, 3, 4, 5, 6) is True
    assert header[WRITE_AT] == 5  # published
    row = rows[1]
    assert rows[0]["t_ns"] == 0 and rows[2]["t_ns"] == 0
    assert [int(row[f]) for f in ("t_ns", "tick", "period_ns", "compute_ns")] == [1, 2, 3, 4]
    assert [int(row[f]) for f in ("lateness_ns", "overruns", "queue_drops")] == [5, 6, 320]
    np.testing.assert_array_equal(row["force"], compiled.force)
    np.testing.assert_array_equal(row["offset"], k.offset)
    np.testing.assert_array_equal(row["commanded_q"], compiled.q_cmd)
    np.testing.assert_allclose(row["zeta"], k.damping / (2 * np.sqrt(k.mass * k.stiffness)))
    np.testing.assert_allclose(row["chi"], np.tanh(compiled.force**2))
    r = pose[:3, :3]
    np.testing.assert_allclose(row["force"][:3], r @ (wrench[:3]), atol=1e-12)
    np.testing.assert_allclose(row["moment"], r @ wrench[3:], atol=1e-12)
    np.testing.assert_array_equal(row["desired_position"], pose[:3, 3])
    np.testing.assert_array_equal(row["desired_orientation"], quaternion)
    header[READ_AT] = header[READ_SEEN_AT] = 2  # the consumer three rows behind: the ring full
    assert put(9, 9, 9, 9, 9, 9) is False
    assert (header[WRITE_AT], header[DROPPED_AT]) == (5, 21) and rows[2]["t_ns"] == 0


@pytest.mark.parametrize("missing", [SENSOR_OK, ROBOT_OK, COMMAND_OK])
def test_stale_input_or_a_command_fault_holds(missing: int) -> None:
    q0 = np.asarray(HOME_Q_RAD)
    _, compiled = pair(q0, GravityCompensator())
    pose = MODEL.fk(q0)
    flags_in = (SENSOR_OK | ROBOT_OK | COMMAND_OK) & ~missing
    result = compiled.run(flags_in, np.zeros(6), q0, np.zeros(6), np.zeros(9),
                          pose[:3, 3].copy(), pose[:3, :3])  # fmt: skip
    assert result & HELD and result & HOLDING
    assert bool(result & FRESH) == (missing == COMMAND_OK)
