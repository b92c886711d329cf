"""A plain client of the rig's three wire protocols, for tests and benchmarks of the rig.

No hilrig driver in the way: pyserial on the F/T pty, a socket on the joint-state stream and a
pymodbus ``ModbusTcpClient`` with RTU framing on the joint-target endpoint, decoded with the
pure codecs (``KunweiFramer``, ``RobotStateDecoder``). Everything is read from the caller's
thread: ``read()`` takes what has arrived (waiting up to ``timeout_s`` for something).

Two ways to write joint targets: ``write()`` waits for the reply (pymodbus's synchronous
client), ``send()`` only sends a pymodbus-framed request on a second connection and ``acks()``
collects the replies later without blocking, as a session's loop does; with ``wait_for_ft()``
(only the sensor wakes the caller) that is a session's traffic, which is what the rig's CPU
benchmark needs: a reply that wakes a waiting client costs the rig tens of microseconds more.
"""

from __future__ import annotations

import select
import socket
from collections.abc import Sequence
from contextlib import suppress

import serial
from pymodbus import FramerType
from pymodbus.client import ModbusTcpClient
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ModbusPDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest

from hilrig.drivers.ft.wire import START_COMMAND, STOP_COMMAND, FtSample, KunweiFramer
from hilrig.drivers.joint_targets.frame import rtu_frame_size
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
        self._pipe: socket.socket | None = None  # send()'s connection, opened by its first call
        self._pipe_rx = bytearray()
        self._request_framer = FramerRTU(DecodePDU(is_server=False))
        self._reply_framer = FramerRTU(DecodePDU(is_server=False))
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

    def wait_for_ft(self, timeout_s: float) -> None:
        """Sleep until the F/T pty has data or ``timeout_s`` passes: as a session's loop waits,
        woken by the sensor only (then ``read()`` takes everything without waiting)."""
        assert self._serial is not None
        select.select([] if self.ft_closed else [self._serial.fileno()], [], [], timeout_s)

    def send(self, q_rad: Sequence[float], sequence: int, mode: Mode = Mode.TRACK) -> None:
        """Send one joint-target write without waiting for its reply (see ``acks()``)."""
        if self._pipe is None:
            self._pipe = socket.create_connection(self._endpoints.modbus, timeout=10)
            self._pipe.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._pipe.setblocking(False)
        registers = self._map.encode(JointTargets(tuple(q_rad), sequence, mode))
        request = WriteMultipleRegistersRequest(
            address=self._map.start, registers=registers, dev_id=self._map.device_id
        )
        self._pipe.sendall(self._request_framer.buildFrame(request))

    def acks(self) -> list[ModbusPDU]:
        """The replies to ``send()`` that have arrived, oldest first (never blocks)."""
        if self._pipe is None:
            return []
        with suppress(BlockingIOError):
            self._pipe_rx += self._pipe.recv(65536)
        replies: list[ModbusPDU] = []
        while size := rtu_frame_size(self._reply_framer.decoder, self._pipe_rx):
            _, reply = self._reply_framer.handleFrame(bytes(self._pipe_rx[:size]), 0, 0)
            del self._pipe_rx[:size]
            if reply is not None:
                replies.append(reply)
        return replies

    def stop_ft(self) -> None:
        """Send the sensor's stop command."""
        assert self._serial is not None
        self._serial.write(STOP_COMMAND)

    def close(self) -> None:
        for closeable in (self._serial, self._sock, self.modbus, self._pipe):
            if closeable is not None:
                closeable.close()

    def __enter__(self) -> RigProbe:
        return self.open()

    def __exit__(self, *_: object) -> None:
        self.close()
