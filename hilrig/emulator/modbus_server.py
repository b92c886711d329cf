"""The robot's Modbus RTU joint-target endpoint, emulated: RTU framing over loopback TCP.

RTU framing (CRC-16, no MBAP header) over TCP on 127.0.0.1 with an OS-chosen port, the way
RTU-over-TCP gateways carry a serial bus. A device of a :class:`SlotLoop` (or alone with
``start()``/``stop()``): the loop accepts clients and answers each request as it arrives, with
pymodbus's own RTU framer and PDU classes decoding requests and encoding replies, so the bytes
on the wire are pymodbus's. Every accepted write of the register map (function 16) is decoded
with ``RegisterMap.decode`` and handed to ``on_targets``; a write elsewhere gets ILLEGAL_ADDRESS,
one that does not decode ILLEGAL_VALUE, any other function ILLEGAL_FUNCTION, and requests for
another device id no reply (as on a bus). ``inject_exceptions`` (any thread) makes the next
writes fail.
"""

from __future__ import annotations

import socket
from collections import deque
from collections.abc import Callable

from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusIOException
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ExceptionResponse, ModbusPDU
from pymodbus.pdu.register_message import (
    WriteMultipleRegistersRequest,
    WriteMultipleRegistersResponse,
)

from hilrig.drivers.joint_targets.frame import rtu_frame_size
from hilrig.drivers.joint_targets.wire import JointTargets, RegisterMap
from hilrig.emulator.slots import Device, SlotLoop, accept_client
from hilrig.errors import ProtocolError

MAX_REQUEST_BYTES = 1024  # unframed bytes beyond which a client's input is discarded
MAX_REGISTERS = 0x7B  # the most function 16 may write (Modbus spec)


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
        on_targets: Callable[[JointTargets], None],
        *,
        register_map: RegisterMap | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        self._map = register_map or RegisterMap()
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
        while client.rx:
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
        if self._fail_next > 0:
            self._fail_next -= 1
            self.exceptions_sent += 1
            return ExceptionResponse(code, self._fail_code, request.dev_id)
        if request.address != self._map.start or request.count != self._map.count:
            self.rejected += 1
            return ExceptionResponse(code, ExcCodes.ILLEGAL_ADDRESS, request.dev_id)
        try:
            targets = self._map.decode(list(request.registers))
        except ProtocolError:
            self.rejected += 1
            return ExceptionResponse(code, ExcCodes.ILLEGAL_VALUE, request.dev_id)
        self.writes += 1
        self._on_targets(targets)
        return WriteMultipleRegistersResponse(
            address=request.address, count=request.count, dev_id=request.dev_id
        )

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
