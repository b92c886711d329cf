"""A plain client of the rig's three wire protocols, for tests and benchmarks of the rig.

No hilrig driver in the way: pyserial on the F/T pty, a socket on the joint-state stream and a
pymodbus ``ModbusTcpClient`` with RTU framing on the joint-target endpoint, decoded with the
pure codecs (``KunweiFramer``, ``RobotStateDecoder``). Everything is read from the caller's
thread: ``read()`` takes what has arrived (waiting up to ``timeout_s`` for something).
"""

from __future__ import annotations

import select
import socket
from collections.abc import Sequence

import serial
from pymodbus import FramerType
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ModbusPDU

from hilrig.drivers.ft.wire import START_COMMAND, STOP_COMMAND, FtSample, KunweiFramer
from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
from hilrig.drivers.robot_state.wire import RobotState, RobotStateDecoder
from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import LinkError

BAUD = 460800


class RigProbe:
    """Reads both streams and writes joint targets; ``with RigProbe(endpoints) as probe:``."""

    def __init__(self, endpoints: RigEndpoints, *, register_map: RegisterMap | None = None) -> None:
        self._endpoints = endpoints
        self._map = register_map or RegisterMap()
        self.ft_framer = KunweiFramer()
        self.state_decoder = RobotStateDecoder()
        self._serial: serial.Serial | None = None
        self._sock: socket.socket | None = None
        self.modbus: ModbusTcpClient | None = None
        self.joint_closed = False  # the rig closed the joint-state stream
        self.ft_closed = False  # the rig closed the pty (stopped, or a dropped link)

    def open(self) -> RigProbe:
        """Open the pty and send the start command, connect the stream and the Modbus client."""
        self._serial = serial.Serial(self._endpoints.ft_wrist_port, BAUD, timeout=0)
        self._serial.write(START_COMMAND)
        self._sock = socket.create_connection(self._endpoints.robot_state, timeout=10)
        self._sock.setblocking(False)
        host, port = self._endpoints.modbus
        self.modbus = ModbusTcpClient(host, port=port, framer=FramerType.RTU, timeout=5)
        if not self.modbus.connect():  # type: ignore[no-untyped-call]
            raise LinkError(f"no Modbus endpoint at {host}:{port}")
        return self

    def read(self, timeout_s: float = 0.0) -> tuple[list[FtSample], list[RobotState]]:
        """F/T samples and joint states that have arrived, after waiting up to ``timeout_s``."""
        assert self._serial is not None and self._sock is not None
        fds = [] if self.ft_closed else [self._serial.fileno()]
        fds += [] if self.joint_closed else [self._sock.fileno()]
        ready, _, _ = select.select(fds, [], [], timeout_s)
        samples: list[FtSample] = []
        states: list[RobotState] = []
        if not self.ft_closed and self._serial.fileno() in ready:
            try:
                samples = self.ft_framer.feed(self._serial.read(65536))
            except serial.SerialException:
                self.ft_closed = True
        if self._sock.fileno() in ready:
            data = self._sock.recv(1 << 20)
            self.joint_closed = not data
            states = self.state_decoder.feed(data)
        return samples, states

    def write(self, q_rad: Sequence[float], sequence: int, mode: Mode = Mode.TRACK) -> ModbusPDU:
        """One joint-target write; returns pymodbus's reply (an exception reply included)."""
        assert self.modbus is not None
        registers = self._map.encode(JointTargets(tuple(q_rad), sequence, mode))
        return self.modbus.write_registers(
            self._map.start, registers, device_id=self._map.device_id
        )

    def stop_ft(self) -> None:
        """Send the sensor's stop command."""
        assert self._serial is not None
        self._serial.write(STOP_COMMAND)

    def close(self) -> None:
        for closeable in (self._serial, self._sock, self.modbus):
            if closeable is not None:
                closeable.close()

    def __enter__(self) -> RigProbe:
        return self.open()

    def __exit__(self, *_: object) -> None:
        self.close()
