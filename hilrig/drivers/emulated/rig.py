"""The emulated rig: an AUBO-i5 and its wrist F/T sensor behind the real wire protocols.

One object owns the pieces, each on the transport the real device uses:

- the wrist F/T sensor on a pty (``FtEmulator``), its wrench from the scenario at the sensor's
  pose (forward kinematics of the plant), plus bias, noise and the tool's gravity;
- the joint-state TCP stream (``EmulatedRobotStateServer``), which advances the plant and reports
  q, qd and the joint modules' torques (scenario plus noise);
- the Modbus RTU-over-TCP joint-target endpoint (``EmulatedModbusServer``), which feeds the
  plant's servos.

Sockets bind 127.0.0.1 on OS-chosen ports unless told otherwise; ``start()`` returns the
endpoints. Faults are injected on the parts (``rig.ft``, ``rig.robot_state``, ``rig.modbus``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hilrig.drivers.emulated.ft_emulator import EmulatorConfig, FtEmulator
from hilrig.drivers.emulated.modbus_server import EmulatedModbusServer
from hilrig.drivers.emulated.plant import JointServoPlant
from hilrig.drivers.emulated.robot_state_server import EmulatedRobotStateServer
from hilrig.drivers.emulated.scenarios import Scenario, scenario
from hilrig.drivers.gravity import ToolLoad
from hilrig.drivers.joint_targets_map import JointTargets
from hilrig.drivers.robot_state_codec import RobotState
from hilrig.robot import RobotModel

HOME_Q_RAD = (0.0, -0.3, 1.6, 0.3, np.pi / 2, 0.0)  # tool 0.58 m out, 0.29 m up, pointing down


@dataclass(frozen=True)
class RigEndpoints:
    """Where a driver finds each device of the rig."""

    ft_wrist_port: str  # serial port path (a pty here)
    robot_state: tuple[str, int]  # TCP host, port
    modbus: tuple[str, int]  # RTU over TCP host, port

    def lines(self) -> list[str]:
        """Human-readable endpoint lines, one per device."""
        return [
            f"wrist F/T sensor (Kunwei, 460800 8N1): {self.ft_wrist_port}",
            f"robot joint state (TCP): {self.robot_state[0]}:{self.robot_state[1]}",
            f"joint targets (Modbus RTU over TCP): {self.modbus[0]}:{self.modbus[1]}",
        ]


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


class _SensorPose:
    """FK of the plant's current q, computed once per F/T frame (emulator thread only)."""

    def __init__(self, plant: JointServoPlant) -> None:
        self._plant = plant
        self._model = RobotModel()
        self._t_s = -1.0
        self._pose = np.eye(4)

    def at(self, t_s: float) -> NDArray[np.float64]:
        if t_s != self._t_s:
            self._pose = self._model.fk(self._plant.q_rad)
            self._t_s = t_s
        return self._pose


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
        self.plant = JointServoPlant(
            RobotModel().limits, q0_rad=np.asarray(self.config.q0_rad, dtype=np.float64)
        )
        self._pose = _SensorPose(self.plant)
        self._rng = np.random.default_rng(self.config.seed)
        self._t0_ns = 0
        self.ft = FtEmulator(
            self._wrench,
            config=self.config.ft,
            orientation=lambda t_s: self._pose.at(t_s)[:3, :3],
            port_path=port_path,
        )
        self.robot_state = EmulatedRobotStateServer(
            self._state, rate_hz=self.config.rate_hz, host=self.config.host
        )
        self.modbus = EmulatedModbusServer(self._targets, host=self.config.host)

    def start(self) -> RigEndpoints:
        self._t0_ns = time.monotonic_ns()
        self.plant.advance(self._t0_ns)
        self.modbus.start()
        self.robot_state.start()
        self.ft.start()
        return self.endpoints

    def stop(self) -> None:
        self.ft.stop()
        self.robot_state.stop()
        self.modbus.stop()

    def __enter__(self) -> RigEndpoints:
        return self.start()

    def __exit__(self, *_: object) -> None:
        self.stop()

    @property
    def endpoints(self) -> RigEndpoints:
        host = self.config.host
        return RigEndpoints(
            str(self.ft.port_path), (host, self.robot_state.port), (host, self.modbus.port)
        )

    def _wrench(self, t_s: float) -> tuple[float, ...]:
        return tuple(self.scenario.wrench_in_sensor(t_s, self._pose.at(t_s)).tolist())

    def _targets(self, targets: JointTargets) -> None:
        self.plant.set_targets(targets, time.monotonic_ns())

    def _state(self, sequence: int) -> RobotState:
        now_ns = time.monotonic_ns()
        self.plant.advance(now_ns)
        t_s = (now_ns - self._t0_ns) / 1e9
        noise = self._rng.normal(scale=self.config.joint_torque_noise_nm, size=6)
        torque = self.scenario.joint_torque(t_s) + noise
        # the emulated controller's clock is this host's monotonic clock (shared by every
        # process here), so a reader can measure the stream's latency from device time
        return self.plant.state(sequence, now_ns, torque)
