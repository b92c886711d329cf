"""The emulated rig: an AUBO-i5 and its wrist F/T sensor behind the real wire protocols.

One object owns the pieces, each on the transport the real device uses:

- the wrist F/T sensor on a pty (``FtEmulator``), its wrench from the scenario at the sensor's
  pose (forward kinematics of the plant), plus bias, noise and the tool's gravity;
- the joint-state TCP stream (``EmulatedRobotStateServer``): q, qd and the joint modules'
  torques (scenario plus noise);
- the Modbus RTU-over-TCP joint-target endpoint (``EmulatedModbusServer``), which feeds the
  plant's servos;
- an AUBO ARCS controller (``rig.arcs``, hilrig/emulator/arcs): its JSON-RPC port
  (``rig.arcs_rpc``: servo mode and servoJoint, which also feed the plant, and the robot's state)
  and its RTDE port (``rig.arcs_rtde``: topics pushed from the slots), as AUBO's own client
  (pyaubo-sdk) speaks them; their joint torques are the joint-state stream's (same slot, same
  noise).

One thread runs them all in a :class:`SlotLoop`: every 1 ms slot advances the plant, computes
the sensor's pose once, sends the joint-state frame, then the F/T frame (so a reader woken by the
F/T frame already has that period's joint state); between slots the loop sleeps in select() and
answers start/stop commands, new clients and Modbus writes as they arrive.

``open()`` binds (127.0.0.1, OS-chosen ports unless told otherwise) and returns the endpoints,
``run()`` runs the loop in the calling thread until ``request_stop()``, ``close()`` closes the
devices; ``start()``/``stop()`` (or ``with``) do the same with the loop in a thread of its own.
Faults are injected on the parts (``rig.ft``, ``rig.robot_state``, ``rig.modbus``, ``rig.arcs``)
from any thread; ``counters()`` says exactly what was sent.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.ft.gravity import ToolLoad
from hilrig.drivers.joint_targets.wire import Mode
from hilrig.drivers.robot_state.wire import FRAME_BYTES, JOINTS, LENGTH, MAGIC
from hilrig.emulator.arcs import (
    ArcsConfig,
    ArcsController,
    EmulatedArcsRpcServer,
    EmulatedArcsRtdeServer,
)
from hilrig.emulator.frame_kernels import state_frame_into
from hilrig.emulator.ft_emulator import EmulatorConfig, FtEmulator
from hilrig.emulator.modbus_server import EmulatedModbusServer
from hilrig.emulator.robot_state_server import EmulatedRobotStateServer
from hilrig.emulator.slots import SlotLoop
from hilrig.robot import RobotModel
from hilrig.robot.kinematics import CompiledChain, fk_into
from hilrig.timing import bound_kernel
from hilrig.world.plant import JointServoPlant
from hilrig.world.scenarios import Scenario, scenario

_NOISE_BLOCK = 64  # rows drawn at once: 1024 took 0.4-1 ms of one slot on a slow machine

HOME_Q_RAD = (0.0, -0.3, 1.6, 0.3, np.pi / 2, 0.0)  # tool 0.58 m out, 0.29 m up, pointing down


@dataclass(frozen=True)
class RigEndpoints:
    """Where a driver finds each device of the rig."""

    ft_wrist_port: str  # serial port path (a pty here)
    robot_state: tuple[str, int] = ("", 0)  # TCP host, port ("": none)
    modbus: tuple[str, int] = ("", 0)  # RTU over TCP host, port ("": none)
    aubo_rpc: tuple[str, int] = ("", 0)  # AUBO ARCS JSON-RPC host, port ("": none)
    aubo_rtde: tuple[str, int] = ("", 0)  # AUBO ARCS RTDE host, port ("": none)

    def lines(self) -> list[str]:
        """Human-readable endpoint lines, one per device served."""
        lines = [f"wrist F/T sensor (Kunwei, 460800 8N1): {self.ft_wrist_port}"]
        for label, (host, port) in (
            ("AUBO ARCS JSON-RPC (TCP)", self.aubo_rpc),
            ("AUBO ARCS RTDE (TCP)", self.aubo_rtde),
            ("robot joint state (TCP)", self.robot_state),
            ("joint targets (Modbus RTU over TCP)", self.modbus),
        ):
            if host:
                lines.append(f"{label}: {host}:{port}")
        return lines


@dataclass(frozen=True)
class RigConfig:
    """Emulated-rig settings: rates in Hz, noise rms in N, N*m (sensor) and N*m (joints)."""

    rate_hz: float = 1000.0
    q0_rad: tuple[float, ...] = HOME_Q_RAD
    host: str = "127.0.0.1"
    ft: EmulatorConfig = field(
        default_factory=lambda: EmulatorConfig(
            noise_force_n=0.05,
            noise_torque_nm=0.002,
            bias_in_sensor=(0.8, -0.5, 1.2, 0.02, -0.01, 0.005),
            tool=ToolLoad(mass_kg=0.5, com_in_sensor_m=(0.0, 0.0, 0.05)),
        )
    )
    joint_torque_noise_nm: float = 0.05
    seed: int = 0
    scenario_starts_at_open: bool = True  # False: its clock waits for start_scenario()
    # True: a clock that waits starts when an ARCS client first enters servo mode (a session
    # on a rig served alone, ``hilrig rig serve``, meets its volunteer on the session's clock)
    scenario_starts_with_servo: bool = False
    arcs_rpc_port: int = 0  # the ARCS JSON-RPC port (0: OS-chosen; a real controller's: 30004)
    arcs_rtde_port: int = 0  # the ARCS RTDE port (0: OS-chosen; a real controller's: 30010)
    arcs: ArcsConfig = field(default_factory=ArcsConfig)  # users, servo timeout, constants


@dataclass(frozen=True)
class RigCounters:
    """What the rig did since it opened: frames and writes exactly, and its slots."""

    ft_frames_sent: int  # F/T frames handed whole to the pty
    ft_frames_dropped: int  # not sent: the pty was full, or closed under them
    ft_slots_skipped: int  # streaming slots without a frame (stalls)
    ft_starts: int  # start commands taken
    ft_stops: int  # stop commands taken
    joint_frames_sent: int  # joint-state frames handed whole to client sockets (all clients)
    joint_frames_dropped: int  # not sent to a slow client, or unsent when its link closed
    joint_ticks: int  # joint-state frames produced
    modbus_writes: int  # target writes applied to the plant (and acknowledged)
    modbus_exceptions_sent: int  # injected exception replies
    modbus_rejected: int  # writes refused: ILLEGAL_ADDRESS or ILLEGAL_VALUE
    slots: int  # slots run
    slots_late: int  # slots begun a period or more after their deadline
    slots_skipped: int  # slots not run at all (the loop fell more than MAX_BEHIND behind)
    slot_lateness_us: tuple[float, float, float]  # p50, p99, max of slot start - deadline
    servo_joints: int = 0  # ARCS servoJoint calls accepted and applied to the plant
    rtde_samples_sent: int = 0  # ARCS RTDE topic messages handed whole to client sockets
    servo_mode: bool = False  # the ARCS controller is in servo mode now


class EmulatedRig:
    """The whole emulated rig; ``with EmulatedRig(...) as endpoints:`` or start()/stop()."""

    def __init__(
        self,
        volunteer: str | Scenario = "paper-end-effector",
        *,
        config: RigConfig | None = None,
        port_path: str | Path | None = None,
    ) -> None:
        self.config = RigConfig() if config is None else config
        self.scenario = scenario(volunteer) if isinstance(volunteer, str) else volunteer
        self._model = RobotModel()
        self.plant = JointServoPlant(
            self._model.limits, q0_rad=np.asarray(self.config.q0_rad, dtype=np.float64)
        )
        q_rad, qd_rad_s = self.plant.live_arrays()
        chain = CompiledChain.from_model(self._model)
        self._pose = np.empty((4, 4))  # the sensor's, this slot (updated in place)
        self._update_pose = bound_kernel(
            fk_into, chain.frames, chain.axes, q_rad, self._pose, last=()
        )
        self._update_pose()
        self._rng = np.random.default_rng(self.config.seed)
        self._noise = np.zeros((_NOISE_BLOCK, 6))  # joint torque noise, used last row first
        self._noise_rows = 0
        self._torque = np.zeros(6)  # the scenario's, this slot
        self._measured = np.zeros(6)  # the joints' torque sensors: scenario plus noise, this slot
        self._state_frame = np.zeros(FRAME_BYTES, dtype=np.uint8)
        self._state_frame[:6] = np.frombuffer(MAGIC + LENGTH.to_bytes(2, "little"), np.uint8)
        self._make_state = bound_kernel(
            state_frame_into,
            self._state_frame,
            np.zeros(3 * JOINTS),
            np.zeros(3, dtype=np.uint32),
            np.zeros(1, dtype=np.int64),
            q_rad,
            qd_rad_s,
            self._measured,
            np.zeros((1, 6)),  # the noise is in _measured already
            last=(0, 0, 0, 0),
        )
        self._slot_t_s = 0.0
        self._scenario_t0_ns: int | None = None  # None: the scenario's clock waits at 0
        self.loop = SlotLoop(round(1e9 / self.config.rate_hz), self._slot)
        self.ft = FtEmulator(
            self._wrench,
            config=self.config.ft,
            orientation=lambda t_s: self._pose[:3, :3],
            port_path=port_path,
        )
        self.robot_state = EmulatedRobotStateServer(
            self._state, rate_hz=self.config.rate_hz, host=self.config.host
        )
        self.modbus = EmulatedModbusServer(self._targets, host=self.config.host)
        limits = self._model.limits
        self.arcs = ArcsController(
            self._arcs_targets,
            q_rad=q_rad,
            qd_rad_s=qd_rad_s,
            torque_nm=self._measured,
            q_limits_rad=(limits.lower_rad(), limits.upper_rad()),
            config=self.config.arcs,
        )
        host = self.config.host
        self.arcs_rpc = EmulatedArcsRpcServer(self.arcs, host=host, port=self.config.arcs_rpc_port)
        self.arcs_rtde = EmulatedArcsRtdeServer(
            self.arcs, rate_hz=self.config.rate_hz, host=host, port=self.config.arcs_rtde_port
        )

    def open(self) -> RigEndpoints:
        """Bind every device to the loop (not running yet); returns the endpoints."""
        self.loop.t0_ns = time.monotonic_ns()
        if self.config.scenario_starts_at_open:
            self._scenario_t0_ns = self.loop.t0_ns
        self.plant.advance(self.loop.t0_ns)
        self.arcs.start(self.loop.t0_ns)
        for device in (self.modbus, self.arcs_rpc, self.arcs_rtde, self.robot_state, self.ft):
            device.attach(self.loop)
        return self.endpoints

    def run(self) -> None:
        """Run the slot loop in this thread until ``request_stop()``."""
        self.loop.run()

    def start_scenario(self) -> None:
        """Start the scenario's clock now (a session calls it at its first tick): until then
        the volunteer's time stands at 0."""
        self._scenario_t0_ns = time.monotonic_ns()

    def request_stop(self) -> None:
        """Make ``run()`` return after the current slot (any thread, or a signal handler)."""
        self.loop.stop()

    def close(self) -> None:
        """Close the devices (after ``run()`` has returned)."""
        self.ft.close()
        self.robot_state.close()
        self.modbus.close()
        self.arcs_rpc.close()
        self.arcs_rtde.close()

    def start(self) -> RigEndpoints:
        """``open()`` and run the loop in a thread of its own."""
        endpoints = self.open()
        self.loop.start_thread("emulated-rig")
        return endpoints

    def stop(self) -> None:
        """Stop the loop's thread and close the devices."""
        self.loop.join()
        self.close()

    def __enter__(self) -> RigEndpoints:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()

    @property
    def endpoints(self) -> RigEndpoints:
        host = self.config.host
        return RigEndpoints(
            str(self.ft.port_path),
            (host, self.robot_state.port),
            (host, self.modbus.port),
            (host, self.arcs_rpc.port),
            (host, self.arcs_rtde.port),
        )

    def counters(self) -> RigCounters:
        """A snapshot of what the rig has done."""
        ft, state, loop = self.ft.stats(), self.robot_state.stats, self.loop
        return RigCounters(
            ft_frames_sent=ft.frames_sent,
            ft_frames_dropped=ft.frames_dropped,
            ft_slots_skipped=ft.slots_skipped,
            ft_starts=ft.starts,
            ft_stops=ft.stops,
            joint_frames_sent=state.frames_sent,
            joint_frames_dropped=state.frames_dropped,
            joint_ticks=state.ticks,
            modbus_writes=self.modbus.writes,
            modbus_exceptions_sent=self.modbus.exceptions_sent,
            modbus_rejected=self.modbus.rejected,
            slots=loop.slots,
            slots_late=loop.slots_late,
            slots_skipped=loop.slots_skipped,
            slot_lateness_us=(
                loop.lateness.quantile_us(0.5),
                loop.lateness.quantile_us(0.99),
                loop.lateness.max_ns / 1000,
            ),
            servo_joints=self.arcs.servo_joints,
            rtde_samples_sent=self.arcs_rtde.frames_sent,
            servo_mode=self.arcs.servo_mode,
        )

    def _slot(self, slot_ns: int, now_ns: int) -> None:
        self.plant.advance(now_ns)
        self._update_pose()
        t0_ns = self._scenario_t0_ns
        self._slot_t_s = 0.0 if t0_ns is None else max(slot_ns - t0_ns, 0) * 1e-9
        self._measure_torques()
        self.arcs.tick(slot_ns)
        self.robot_state.tick(slot_ns)
        self.ft.tick(slot_ns)
        self.modbus.tick(slot_ns)
        self.arcs_rpc.tick(slot_ns)
        self.arcs_rtde.tick(slot_ns)

    def _wrench(self, t_s: float) -> tuple[float, ...]:
        """The sensor's wrench at this slot, on the scenario's clock (``t_s``, the sensor's own
        time since the loop opened, runs ahead of it until the session's first tick)."""
        return self.scenario.wrench_in_sensor(self._slot_t_s, self._pose)

    def _arcs_targets(
        self, q_rad: NDArray[np.float64], sequence: int, mode: Mode, now_ns: int
    ) -> None:
        """The ARCS controller's targets to the plant; servo mode's first start may start the
        scenario's clock (``scenario_starts_with_servo``)."""
        if (
            self._scenario_t0_ns is None
            and self.config.scenario_starts_with_servo
            and self.arcs.servo_mode
        ):
            self._scenario_t0_ns = now_ns
        self.plant.set_targets(q_rad, sequence, mode, now_ns)

    def _targets(self, q_rad: NDArray[np.float64], sequence: int, mode: Mode) -> None:
        self.plant.set_targets(q_rad, sequence, mode, time.monotonic_ns())

    def _measure_torques(self) -> None:
        """This slot's joint torque sensors, once for every device: the scenario's joint
        torques plus one row of noise."""
        if not self._noise_rows:  # in place: normal(0, scale) is scale times the standard draw
            self._rng.standard_normal(out=self._noise)
            self._noise *= self.config.joint_torque_noise_nm
            self._noise_rows = _NOISE_BLOCK
        self._noise_rows -= 1
        self._torque[:] = self.scenario.joint_torque(self._slot_t_s)
        np.add(self._torque, self._noise[self._noise_rows], out=self._measured)

    def _state(self, sequence: int) -> bytes:
        """This slot's joint-state frame: the plant's q and qd and the joints' measured torques
        (one compiled call)."""
        # the emulated controller's clock is this host's monotonic clock (shared by every
        # process here), so a reader can measure the stream's latency from device time
        status = int(self.plant.status())
        self._make_state(0, sequence, time.monotonic_ns(), status)
        return self._state_frame.tobytes()
