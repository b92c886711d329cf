"""The robot's Modbus RTU joint-target endpoint, emulated: RTU framing over loopback TCP.

RTU framing (CRC-16, no MBAP header) over TCP on 127.0.0.1 with an OS-chosen port, the way
RTU-over-TCP gateways carry a serial bus. A device of a :class:`SlotLoop` (or alone with
``start()``/``stop()``): the loop accepts clients and answers each request as it arrives, with
pymodbus's own RTU framer and PDU classes decoding requests and encoding replies, so the bytes
on the wire are pymodbus's. Every accepted write of the register map (function 16) is decoded
with ``RegisterMap.decode`` and handed to ``on_targets`` (targets, counter, mode); a write
elsewhere gets ILLEGAL_ADDRESS, one that does not decode ILLEGAL_VALUE, any other function
ILLEGAL_FUNCTION, and requests for another device id no reply (as on a bus).
``inject_exceptions`` (any thread) makes the next writes fail.

A request that is exactly a write of the whole register map (device id, function, address,
count and byte count as the map's, valid CRC) takes a compiled fast path: one call
(``RequestReader``) checks its CRC and decodes it into an array, and the acknowledgement is
pymodbus's, built once. pymodbus's decoding of a request costs about 20 us of Python here, a
tenth of the rig's slot, at 1 kHz. Everything else goes through pymodbus; ``pymodbus_only=True``
sends every request that way, the reference against which
``tests/emulator/test_emulated_modbus_fast_path.py`` checks the fast path.
"""

from __future__ import annotations

import socket
import struct
from collections import deque
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusIOException
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ExceptionResponse, ModbusPDU
from pymodbus.pdu.register_message import (
    WriteMultipleRegistersRequest,
    WriteMultipleRegistersResponse,
)

from hilrig.drivers.joint_targets.frame import BAD_CRC, RequestReader, rtu_frame_size
from hilrig.drivers.joint_targets.wire import JOINTS, Mode, RegisterMap
from hilrig.emulator.slots import Device, SlotLoop, accept_client
from hilrig.errors import ProtocolError

MAX_REQUEST_BYTES = 1024  # unframed bytes beyond which a client's input is discarded
MAX_REGISTERS = 0x7B  # the most function 16 may write (Modbus spec)
WRITE_REGISTERS = 0x10  # function 16, write multiple registers


class TargetsSink(Protocol):
    """Takes each applied write: targets (rad; an array valid only during the call), the
    watchdog counter and the mode."""

    def __call__(self, q_rad: NDArray[np.float64], sequence: int, mode: Mode) -> None: ...


class _Client:
    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.framer = FramerRTU(DecodePDU(is_server=True))
        self.rx = bytearray()


class EmulatedModbusServer(Device):
    """A Modbus RTU-over-TCP server holding the joint-target register map.

    ``port`` is the bound port from construction; ``writes``, ``exceptions_sent`` (injected)
    and ``rejected`` (bad address or values) count requests answered.
    """

    standalone_period_ns = 1_000_000  # requests are answered at the start of each slot
    thread_name = "modbus"

    def __init__(
        self,
        on_targets: TargetsSink,
        *,
        register_map: RegisterMap | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        pymodbus_only: bool = False,
    ) -> None:
        self._map = register_map = register_map or RegisterMap()
        start, count, dev_id = register_map.start, register_map.count, register_map.device_id
        # a whole-map write: its first 7 bytes, its compiled reader (loaded or compiled now,
        # not in a slot on the session's first request), and pymodbus's acknowledgement
        self._write_header = struct.pack(">BBHHB", dev_id, WRITE_REGISTERS, start, count, 2 * count)
        self._reader = None if pymodbus_only else RequestReader(register_map)
        self._ack = FramerRTU(DecodePDU(is_server=True)).buildFrame(
            WriteMultipleRegistersResponse(address=start, count=count, dev_id=dev_id)
        )
        self._q_rad = np.zeros(JOINTS)  # a write decoded by pymodbus, as handed on
        self._on_targets = on_targets
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._loop: SlotLoop | None = None
        self._clients: dict[int, _Client] = {}
        self._requests: deque[tuple[int, ExcCodes]] = deque()
        self._fail_next = 0
        self._fail_code = ExcCodes.DEVICE_BUSY
        self.writes = 0
        self.exceptions_sent = 0
        self.rejected = 0

    def attach(self, loop: SlotLoop) -> None:
        """Accept clients and answer their requests in ``loop`` from now on."""
        self._loop = loop
        loop.watch(self._listener.fileno(), self._accept)

    def tick(self, slot_ns: int) -> None:
        """Take requested faults (requests themselves are answered as they arrive)."""
        self._take_faults()

    def _take_faults(self) -> None:
        while self._requests:
            self._fail_next, self._fail_code = self._requests.popleft()

    def close(self) -> None:
        """Close every client and the listening socket."""
        for fd in list(self._clients):
            self._close(fd)
        if self._loop is not None:
            self._loop.unwatch(self._listener.fileno())
        self._listener.close()

    def inject_exceptions(self, count: int, code: ExcCodes = ExcCodes.DEVICE_BUSY) -> None:
        """Answer the next ``count`` writes with Modbus exception ``code`` (nothing applied)."""
        self._requests.append((count, ExcCodes(code)))

    # -- the loop's thread -------------------------------------------------------------------

    def _accept(self) -> None:
        sock = accept_client(self._listener)
        if sock is None:
            return
        fd = sock.fileno()
        self._clients[fd] = _Client(sock)
        assert self._loop is not None
        self._loop.watch(fd, lambda: self._read(fd))

    def _read(self, fd: int) -> None:
        client = self._clients[fd]
        try:
            data = client.sock.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._close(fd)
            return
        client.rx += data
        reader = self._reader
        while client.rx:
            if reader is not None and client.rx.startswith(self._write_header):
                if len(client.rx) < reader.size:
                    return  # the rest comes with the next segment
                result = reader.read(client.rx)
                if result != BAD_CRC:
                    frame = self._answer_write(client, reader, result)
                    del client.rx[: reader.size]
                    if not self._send(fd, frame):
                        return
                    continue
            size = rtu_frame_size(client.framer.decoder, client.rx)  # requests may be pipelined
            if size == 0:
                if len(client.rx) > MAX_REQUEST_BYTES:
                    client.rx.clear()
                return
            try:
                used, request = client.framer.handleFrame(bytes(client.rx[:size]), 0, 0)
            except ModbusIOException as exc:  # framed but not decodable: as pymodbus's server
                client.rx.clear()
                reply: ModbusPDU | None = ExceptionResponse(
                    exc.fcode or 0, ExcCodes.ILLEGAL_FUNCTION, exc.dev_id
                )
            else:
                del client.rx[:used]
                if request is None:
                    if used:
                        continue  # a frame dropped whole (its CRC failed): others may follow
                    if len(client.rx) > MAX_REQUEST_BYTES:
                        client.rx.clear()
                    return
                reply = self._answer(request)
            if reply is not None and not self._send(fd, client.framer.buildFrame(reply)):
                return

    def _answer(self, request: ModbusPDU) -> ModbusPDU | None:
        """The reply to one request, or None for another device's request."""
        if request.dev_id != self._map.device_id:
            return None
        self._take_faults()  # one injected before this request applies to it
        code = request.function_code
        if not isinstance(request, WriteMultipleRegistersRequest):
            return ExceptionResponse(code, ExcCodes.ILLEGAL_FUNCTION, request.dev_id)
        if not 1 <= request.count <= MAX_REGISTERS or len(request.registers) != request.count:
            return ExceptionResponse(code, ExcCodes.ILLEGAL_VALUE, request.dev_id)
        if (injected := self._injected()) is not None:
            return ExceptionResponse(code, injected, request.dev_id)
        if request.address != self._map.start or request.count != self._map.count:
            self.rejected += 1
            return ExceptionResponse(code, ExcCodes.ILLEGAL_ADDRESS, request.dev_id)
        refused = self._apply_registers(list(request.registers))
        if refused is not None:
            return ExceptionResponse(code, refused, request.dev_id)
        return WriteMultipleRegistersResponse(
            address=request.address, count=request.count, dev_id=request.dev_id
        )

    def _answer_write(self, client: _Client, reader: RequestReader, result: int) -> bytes:
        """The reply frame to the whole-map write (valid CRC) that ``reader`` read into
        ``result`` (``sequence << 16 | mode``, or why it does not decode)."""
        self._take_faults()
        refused = self._injected()
        if refused is None:
            if result < 0:
                self.rejected += 1
                refused = ExcCodes.ILLEGAL_VALUE
            else:
                self.writes += 1
                self._on_targets(reader.q_rad, result >> 16, reader.mode(result))
        if refused is None:
            return self._ack
        reply = ExceptionResponse(WRITE_REGISTERS, refused, self._map.device_id)
        frame: bytes = client.framer.buildFrame(reply)
        return frame

    def _injected(self) -> ExcCodes | None:
        """The injected exception this write gets, if one is left (counted)."""
        if self._fail_next <= 0:
            return None
        self._fail_next -= 1
        self.exceptions_sent += 1
        return self._fail_code

    def _apply_registers(self, registers: list[int]) -> ExcCodes | None:
        """Hand a write of the register map (decoded by pymodbus) on; None, or why it was
        refused."""
        try:
            targets = self._map.decode(registers)
        except ProtocolError:
            self.rejected += 1
            return ExcCodes.ILLEGAL_VALUE
        self.writes += 1
        self._q_rad[:] = targets.q_rad
        self._on_targets(self._q_rad, targets.sequence, targets.mode)
        return None

    def _send(self, fd: int, frame: bytes) -> bool:
        """Send a reply (a few bytes: the socket buffer takes them); False if the link died."""
        try:
            self._clients[fd].sock.sendall(frame)
        except OSError:
            self._close(fd)
            return False
        return True

    def _close(self, fd: int) -> None:
        client = self._clients.pop(fd)
        if self._loop is not None:
            self._loop.unwatch(fd)
        client.sock.close()
