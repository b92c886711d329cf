"""Numba's first-call costs paid before a session's devices talk (see :func:`warm_up`)."""

from __future__ import annotations

import numpy as np

from hilrig.control import combine, make, preset
from hilrig.drivers.ft.frames import FtFrames
from hilrig.drivers.ft.gravity import GravityCompensator
from hilrig.drivers.joint_targets.frame import RequestFrame
from hilrig.drivers.joint_targets.wire import Mode, RegisterMap
from hilrig.drivers.robot_state.frames import StateFrames
from hilrig.emulator.rig import HOME_Q_RAD
from hilrig.rig.arcs.shared import Rings, RingSpecs, newest_row, take_rows
from hilrig.rig.loop_figures import LoopSummary
from hilrig.rig.recorder_feed import RecorderFeed
from hilrig.rig.records import AXES, FT_DTYPE, JOINT_DTYPE
from hilrig.robot import RobotModel
from hilrig.tick.kernel import COMMAND_OK, ROBOT_OK, SENSOR_OK, CompiledTick
from hilrig.tick.loop_step import loop_words
from hilrig.tick.safety import SafetyClamp, SafetyConfig
from hilrig.tick.trajectory import make_trajectory
from hilrig.tick.trajectory_kernel import desired_writer
from hilrig.timing import LatencyHistogram


def warm_up() -> None:
    """Load (or compile) every kernel the session's thread runs once its devices talk (the
    tick's, the task trajectory's samplers, the drivers' decoders, the Modbus request's, the
    rings' row stores, the ARCS link's ring readers, the loop's latency histograms) and run
    them once on a throwaway state built like a session's (rows in shared-memory rings: numba
    compiles per array type), so
    that no first-call cost lands between the devices' first bytes and the session's first
    ticks (a fresh clone compiles them all here; ``tests/rig/test_warm_up.py`` checks that
    nothing is left)."""
    model = RobotModel()
    q0 = np.asarray(HOME_Q_RAD, dtype=np.float64)
    controller = make("adaptive", combine((preset("adaptive"), 3), (preset("adaptive-joint"), 6)))
    clamp = SafetyClamp(SafetyConfig(), model, q0)
    tick = CompiledTick.build(controller, model, clamp, GravityCompensator(), q0, 0.001)
    start = model.fk(q0)
    trajectory = make_trajectory("hold", start)
    position = np.zeros(3)
    desired_writer(make_trajectory("circle", start), position)(0.0)  # the circle's sampler
    desired_writer(trajectory, position)(0.0)  # the waypoints' (square, hold)
    zeros6 = np.zeros(6)
    flags = SENSOR_OK | ROBOT_OK | COMMAND_OK
    tick.run(flags, zeros6, q0, zeros6, np.zeros(AXES), position, trajectory.rotation)
    newest = (np.zeros(1, dtype=FT_DTYPE), np.zeros(1, dtype=JOINT_DTYPE))
    tick.loop_step(*newest, loop_words(0))(0)  # the live loop's
    RequestFrame(RegisterMap()).fill(q0, 0, Mode.HOLD)  # the Modbus request's kernels
    FtFrames()  # the drivers' decoders compile as they are made
    StateFrames()
    LatencyHistogram().add(0)
    LoopSummary().period_adder()(0, 0, 0, 0)
    feed = RecorderFeed(rows=2, events=1)  # rings as the session's
    try:
        for ring in (feed.ft, feed.joint):  # the drivers' rows into their rings, both ways
            ring.put(np.zeros(1, dtype=ring.spec.dtype))
            ring.feed_from(np.zeros(1, dtype=ring.spec.dtype))
            ring.put_first(1)
        feed.servo.put(np.zeros(1, dtype=feed.servo.spec.dtype))  # the servo calls' rows
        put_row = tick.row_writer(feed.tick.rows, feed.tick.header, feed.headers)
        put_row(0, 0, 0, 0, 0, 0)
        del put_row  # it holds the ring's rows, which must be released before unmapping
    finally:
        feed.close()
    arcs = Rings.create(RingSpecs.unique())  # the ARCS link's rings, read both ways
    try:
        for ring in (arcs.states, arcs.servo, arcs.commands):
            take_rows(ring.rows, ring.header, np.zeros(1, dtype=ring.spec.dtype))
            newest_row(ring.rows, ring.header, np.zeros(1, dtype=ring.spec.dtype))
    finally:
        arcs.close()
