"""The real-time loop: read -> compensate -> control -> IK -> clamp -> command -> log, each tick.

One tick (DESIGN.md, The loop and safety): the newest wrist F/T sample is tared and freed of the
tool's gravity, rotated into the base frame and, with the joint modules' torques, fed to one
9-axis admittance controller (3 Cartesian axes, then 6 joints: two axis groups); the offsets
move the task pose X_r = X_d + e, inverse kinematics (warm-started) gives joint targets, to which
the joint offsets are added; the safety clamp bounds them and the Modbus writer takes them
without blocking. Stale sensor data or a lost robot link holds the last safe pose (a controlled
stop); a force above the protective limit stops the robot (Modbus mode STOP, latched). Every
device sample and every tick goes to the recorder's rings, which never block; the tick's own
period, compute time and lateness are logged with it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hilrig.control import AdmittanceController, Law, combine, make, resolve_params
from hilrig.control.controller import ParamsLike
from hilrig.drivers.base import Reader
from hilrig.drivers.ft_sensor import FtSample
from hilrig.drivers.gravity import GravityCompensator
from hilrig.drivers.joint_targets import JointTargetsWriter
from hilrig.drivers.joint_targets_map import Mode
from hilrig.drivers.robot_state import ReceivedState
from hilrig.recording.samples import EventRecord
from hilrig.rig.events import EventDetector
from hilrig.rig.recorder import RecorderFeed
from hilrig.rig.records import JOINTS
from hilrig.rig.safety import SafetyClamp
from hilrig.rig.timing import DeadlineTimer, LatencyHistogram, realtime_python
from hilrig.rig.trajectory import Trajectory
from hilrig.rig.virtual import VirtualInput
from hilrig.robot import RobotModel

COMMAND_FAULT_HOLD_NS = 50_000_000  # after a failed joint-target write, hold this long
IK_TOLERANCE = 1e-8  # m and rad: warm-started, one Gauss-Newton step a tick meets it


@dataclass(frozen=True)
class LoopConfig:
    """What the loop runs: rate (Hz), law and parameters of each axis group, staleness limit."""

    rate_hz: float = 1000.0
    law: str = "adaptive"
    cartesian_params: ParamsLike = "adaptive"
    joint_params: ParamsLike = "adaptive-joint"
    stale_after_ticks: int = 5
    spin_us: int = 150
    ik_max_iterations: int = 2

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.rate_hz)

    def controller(self) -> AdmittanceController:
        """The 9-axis controller (Cartesian group, joint group); raises ParameterError."""
        params = combine(
            (resolve_params(self.cartesian_params), 3), (resolve_params(self.joint_params), 6)
        )
        return make(Law(self.law), params, dt=1.0 / self.rate_hz)

    def params_record(self) -> dict[str, Any]:
        """The parameters as plain values, for the session metadata."""
        params = self.controller().params
        return {
            "law": self.law,
            "rate_hz": self.rate_hz,
            **{k: str(v) for k, v in params.__dict__.items() if v is not None},
        }


@dataclass
class LoopStatus:
    """What the status line shows; written by the loop, read by anyone (plain values)."""

    ticks: int = 0
    lateness_us: float = 0.0
    force_n: float = 0.0
    offset_mm: float = 0.0
    contact: str = "free"
    holding: str = ""
    drops: int = 0
    stopped: bool = False


@dataclass
class LoopSummary:
    """End-of-run numbers: tick counts, lateness and sensor-to-command latency histograms."""

    ticks: int = 0
    missed_deadlines: int = 0  # ticks whose work ended after the next deadline
    skipped_ticks: int = 0
    hold_ticks: int = 0
    lateness: LatencyHistogram = field(default_factory=LatencyHistogram)
    compute: LatencyHistogram = field(default_factory=LatencyHistogram)
    sensor_to_command: LatencyHistogram = field(default_factory=LatencyHistogram)


class ControlLoop:
    """The tick and its pacing; devices are connected before and closed after ``run``."""

    def __init__(
        self,
        config: LoopConfig,
        *,
        sensor: Reader[FtSample],
        robot: Reader[ReceivedState],
        targets: JointTargetsWriter,
        compensator: GravityCompensator,
        trajectory: Trajectory,
        safety: SafetyClamp,
        model: RobotModel,
        feed: RecorderFeed | None = None,
        on_event: Callable[[EventRecord], None] | None = None,
        virtual: VirtualInput | None = None,
    ) -> None:
        self.config = config
        self._sensor = sensor
        self._robot = robot
        self._targets = targets
        self._compensator = compensator
        self._trajectory = trajectory
        self._safety = safety
        self._model = model
        self._feed = feed
        self._controller = config.controller()
        params = self._controller.params
        self._mass = params.per_axis("m", 9)
        self._zeta = np.zeros(9)
        self._events = EventDetector(on_event=self._event)
        self._on_event = on_event
        self._virtual = virtual
        self._playing = False
        self.status = LoopStatus()
        self.summary = LoopSummary()
        self._stale_ns = config.stale_after_ticks * config.period_ns
        # preallocated tick buffers
        self._force = np.zeros(9)
        self._fresh = np.zeros(9)
        self._wrench = np.zeros(6)
        self._x_r = np.eye(4)
        self._q_ik = np.zeros(JOINTS)
        self._q_cmd = np.zeros(JOINTS)
        self._q_target = np.zeros(JOINTS)
        self._chi = np.zeros(9)
        self._moment = np.zeros(3)
        self._position = np.zeros(3)
        self._stopped = False
        self._command_errors = targets.errors
        self._command_hold_until_ns = 0
        self._t0_ns = 0
        self._last_start_ns = 0
        self._written = 0

    def _event(self, record: EventRecord) -> None:
        if self._feed is not None:
            self._feed.event(record)
        if self._on_event is not None:
            self._on_event(record)

    def run(self, duration_s: float | None, stop: threading.Event) -> LoopSummary:
        """Tick until ``duration_s`` has passed or ``stop`` is set; returns the summary."""
        robot = self._robot.latest()
        if robot is None:
            raise RuntimeError("run() needs a robot state: connect the robot first")
        self._q_ik[:] = robot.state.q_rad
        self._q_cmd[:] = robot.state.q_rad
        self._x_r[:] = self._model.fk(self._q_ik)
        self._warm_up()
        timer = DeadlineTimer(self.config.period_ns, spin_ns=self.config.spin_us * 1000)
        summary = self.summary
        with realtime_python():  # first: its one garbage collection must not delay tick 1
            self._t0_ns = time.monotonic_ns()
            timer.start(self._t0_ns)
            end_ns = None if duration_s is None else self._t0_ns + round(duration_s * 1e9)
            while not stop.is_set():
                start_ns, lateness_ns = timer.wait()
                if end_ns is not None and start_ns >= end_ns:
                    break
                self.tick(start_ns, lateness_ns, timer)
                compute_ns = time.monotonic_ns() - start_ns
                summary.compute.add(compute_ns)
                summary.lateness.add(lateness_ns)
                if lateness_ns + compute_ns > self.config.period_ns:
                    summary.missed_deadlines += 1
        summary.skipped_ticks = timer.skipped
        self._targets.write(self._q_cmd, Mode.HOLD)
        return summary

    def _warm_up(self) -> None:
        """Pay every first-call cost before the first deadline, not on tick 1: the compiled
        kernel's load, IK's first solve, and the event queue's feeder thread (started by the
        session-start event)."""
        self._controller.step(np.zeros(9))
        self._controller.reset()
        self._model.ik(self._x_r, self._q_ik, max_iterations=1)
        self._events.mark("loop", "session started at the start pose", time.monotonic_ns())

    def tick(self, start_ns: int, lateness_ns: int, timer: DeadlineTimer) -> None:
        """One control tick started at ``start_ns`` (monotonic), ``lateness_ns`` after deadline."""
        summary = self.summary
        feed = self._feed
        for ft in self._sensor.drain():
            if feed is not None and (row := feed.ft_slot()) is not None:
                row["t_ns"] = ft.t_ns
                row["seq"] = ft.seq
                row["wrench"] = ft.wrench_in_sensor
                feed.commit_ft()
        for received in self._robot.drain():
            if feed is not None and (row := feed.joint_slot()) is not None:
                state = received.state
                row["t_ns"] = received.t_ns
                row["device_t_ns"] = state.device_t_ns
                row["seq"] = state.sequence
                row["q"] = state.q_rad
                row["qd"] = state.qd_rad_s
                row["tau"] = state.torque_nm
                feed.commit_joint()
        sample = self._sensor.latest()
        robot = self._robot.latest()
        sensor_ok = sample is not None and start_ns - sample.t_ns <= self._stale_ns
        robot_ok = robot is not None and start_ns - robot.t_ns <= self._stale_ns
        self._events.link("wrist F/T sensor", sensor_ok, start_ns)
        self._events.link("robot joint state", robot_ok, start_ns)
        command_errors = self._targets.errors
        if command_errors != self._command_errors:  # a Modbus exception, timeout or lost link
            self._command_errors = command_errors
            self._command_hold_until_ns = start_ns + COMMAND_FAULT_HOLD_NS
            self._events.fault("joint targets", str(self._targets.last_error), start_ns)
        command_ok = start_ns >= self._command_hold_until_ns
        # the task is sampled at the tick's nominal time (its deadline), not its jittery start,
        # so the commanded path is as smooth as the controller's fixed dt assumes
        t_s = (start_ns - lateness_ns - self._t0_ns - self.config.period_ns) / 1e9
        self._trajectory.desired(t_s, self._position)
        fresh = sensor_ok and robot_ok
        if fresh:
            assert sample is not None and robot is not None
            r_base_sensor = self._model.fk(np.asarray(robot.state.q_rad))[:3, :3]
            self._compensator.compensate(sample.wrench_in_sensor, r_base_sensor, out=self._wrench)
            np.matmul(r_base_sensor, self._wrench[:3], out=self._fresh[:3])
            self._fresh[3:] = robot.state.torque_nm
            if self._virtual is not None:
                self._play(t_s, start_ns)
            # drivers reject non-finite values; anything that still overflows here is stale
            fresh = bool(np.isfinite(self._fresh).all() and np.isfinite(self._wrench).all())
        if fresh:
            self._force[:] = self._fresh
            np.matmul(r_base_sensor, self._wrench[3:], out=self._moment)
            if not self._stopped and self._safety.stop_required(self._force[:3], self._force[3:]):
                self._stopped = True
                norm_n = math.hypot(*self._force[:3])
                self._events.fault(
                    "safety", "protective limit: robot stopped", start_ns, value=norm_n
                )
        # The controller steps on every tick, on the last fresh input while inputs are stale, so
        # the recorded /controller/state is exactly the replay of the recorded /controller/input.
        offsets = self._controller.step(self._force)
        self._events.contact(self._controller.contact, start_ns)
        holding = ""
        source_ns = 0  # no fresh sensor input behind a hold
        if not (fresh and command_ok) or self._stopped:
            holding = "stopped" if self._stopped else ("command fault" if fresh else "stale input")
            flags = self._safety.hold(self._q_cmd)
            summary.hold_ticks += 1
        else:
            assert sample is not None
            self._x_r[:3, 3] = self._position + offsets[:3]
            self._x_r[:3, :3] = self._trajectory.rotation
            # a tight tolerance makes IK follow the path every tick (one step); the default 1e-6
            # lets it idle and then catch up in one jump the clamp reads as acceleration
            result = self._model.ik(
                self._x_r,
                self._q_ik,
                max_iterations=self.config.ik_max_iterations,
                tol_position_m=IK_TOLERANCE,
                tol_rotation_rad=IK_TOLERANCE,
            )
            self._q_ik[:] = result.q_rad
            np.add(self._q_ik, offsets[3:], out=self._q_target)
            flags = self._safety.clamp(self._q_target, self._q_cmd)
            source_ns = sample.t_ns
        self._events.clamp(int(flags), start_ns)
        # a protective stop stays latched: every later write repeats STOP
        mode = Mode.STOP if self._stopped else Mode.TRACK
        self._targets.write(self._q_cmd, mode, source_ns=source_ns)
        self._track_latency()
        self.status.holding = holding
        self._log_tick(start_ns, lateness_ns, timer)

    def _play(self, t_s: float, t_ns: int) -> None:
        """Add the virtual collision's row for ``t_s`` to the fresh input; mark start and end."""
        assert self._virtual is not None
        playing = self._virtual.add_to(t_s, self._fresh)
        if playing != self._playing:
            self._playing = playing
            what = "started" if playing else "ended"
            self._events.mark("virtual collision", f"playback {what}", t_ns)

    def _track_latency(self) -> None:
        """Sensor-to-command: F/T arrival of the input of the last acknowledged write -> ack."""
        stats = self._targets.stats
        if stats.written != self._written:
            self._written = stats.written
            source_ns = stats.last_source_ns
            if source_ns:
                self.summary.sensor_to_command.add(stats.last_write_ns - source_ns)

    def _log_tick(self, start_ns: int, lateness_ns: int, timer: DeadlineTimer) -> None:
        summary = self.summary
        summary.ticks += 1
        controller = self._controller
        feed = self._feed
        if feed is not None and (row := feed.tick_slot()) is not None:
            row["t_ns"] = start_ns
            row["tick"] = summary.ticks
            row["force"] = self._force
            row["moment"] = self._moment
            row["offset"] = controller.offset
            row["offset_rate"] = controller.velocity
            row["damping"] = controller.damping
            row["stiffness"] = controller.stiffness
            np.multiply(self._force, self._force, out=self._chi)
            row["chi"] = np.tanh(self._chi, out=self._chi)
            # zeta = b / (2 sqrt(m k)), into a buffer: the property would allocate
            np.multiply(self._mass, controller.stiffness, out=self._zeta)
            np.sqrt(self._zeta, out=self._zeta)
            np.divide(controller.damping, self._zeta, out=self._zeta)
            row["zeta"] = np.multiply(self._zeta, 0.5, out=self._zeta)
            row["contact"] = controller.contact
            row["desired_position"] = self._position
            row["desired_orientation"] = self._trajectory.orientation
            row["commanded_q"] = self._q_cmd
            row["period_ns"] = start_ns - self._last_start_ns if self._last_start_ns else 0
            row["compute_ns"] = time.monotonic_ns() - start_ns
            row["lateness_ns"] = lateness_ns
            row["overruns"] = summary.missed_deadlines
            row["queue_drops"] = feed.drops
            feed.commit_tick()
        self._last_start_ns = start_ns
        status = self.status
        status.ticks = summary.ticks
        status.lateness_us = lateness_ns / 1000
        force, offset = self._force, controller.offset
        status.force_n = math.hypot(force[0], force[1], force[2])
        status.offset_mm = 1000 * math.hypot(offset[0], offset[1], offset[2])
        status.drops = 0 if feed is None else feed.drops
        status.stopped = self._stopped
