"""Joint targets to the robot over Modbus RTU (function 16), sent from the caller's loop.

``write(q_rad)`` never blocks: it encodes the register map (joint_targets/wire.py) with a fresh
watchdog counter and sends the request at once if fewer than ``max_in_flight`` requests await
replies; otherwise the targets wait as the pending latest value (a newer write supersedes them,
counted: the robot should only ever get the newest) and leave from ``poll`` as soon as a reply
frees a slot. ``poll(now_ns)`` reads replies without blocking and matches them to the requests
in order: acknowledged writes, Modbus exception replies (ModbusExceptionError, counted by code)
and timeouts (no reply within the endpoint's ``timeout_s``: the link is dropped and reopened
with backoff) are counted. Nothing raises: the last error is kept in ``last_error``. No thread.

Frames are pymodbus's: a request is pymodbus's template filled in place by a compiled kernel
(:class:`~hilrig.drivers.joint_targets.frame.RequestFrame`, checked byte for byte against
pymodbus; pymodbus per request costs tens of us here); the acknowledgement, the same 8 bytes for
every write of a register map, is built once by pymodbus and compared byte for byte; any other
reply is cut by pymodbus's sizing and decoded by pymodbus (``FramerRTU.handleFrame``).
"""

from __future__ import annotations

import contextlib
import os
import socket
import time
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import serial
from numpy.typing import ArrayLike
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusException
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ModbusPDU
from pymodbus.pdu.register_message import WriteMultipleRegistersResponse

from hilrig.drivers.base import LinkStatus, Writer, error_text, wait_readable
from hilrig.drivers.joint_targets.frame import RequestFrame, rtu_frame_size
from hilrig.drivers.joint_targets.wire import Mode, RegisterMap
from hilrig.drivers.reconnect import Backoff, start_tcp_connect, tcp_connected
from hilrig.errors import LinkError, ModbusExceptionError, ParameterError, ProtocolError

READ_BYTES = 4096


@dataclass(frozen=True)
class ModbusEndpoint:
    """Where the joint-target registers are: RTU over TCP (host, port) or a serial port path."""

    host: str = "127.0.0.1"
    port: int = 502
    serial_port: str | None = None  # e.g. /dev/ttyUSB0; set to use the serial bus instead
    baudrate: int = 115200
    timeout_s: float = 0.05  # a request unanswered for this long drops the link
    connect_timeout_s: float = 1.0  # a TCP connect not done by then is abandoned (backoff)

    def __str__(self) -> str:
        return self.serial_port or f"rtu+tcp://{self.host}:{self.port}"


@dataclass
class WriterStats:
    """Counters since the writer was made; ``exceptions`` counts Modbus exception codes."""

    submitted: int = 0
    sent: int = 0  # requests sent
    written: int = 0  # requests acknowledged
    superseded: int = 0
    refused: int = 0  # submits with non-finite targets, never sent
    timeouts: int = 0
    reconnects: int = 0
    in_flight: int = 0  # requests sent and awaiting their reply
    exceptions: dict[int, int] = field(default_factory=dict)
    last_sent_ns: int = 0  # time.monotonic_ns() once the last request's send returned
    last_sent_source_ns: int = 0  # the source time given with the last request sent
    last_write_ns: int = 0  # the poll time that read the last acknowledgement
    last_latency_ns: int = 0  # submit -> acknowledged, of the last acknowledged write
    last_source_ns: int = 0  # the source time given with the last acknowledged write (or 0)


class _Request(NamedTuple):
    sequence: int
    submitted_ns: int
    source_ns: int
    sent_ns: int


class JointTargetsWriter(Writer[ArrayLike]):
    """Writes the newest joint targets to the robot; ``with writer:`` connects and closes."""

    def __init__(
        self,
        endpoint: ModbusEndpoint,
        *,
        register_map: RegisterMap | None = None,
        max_in_flight: int = 1,
        backoff_s: tuple[float, float] = (0.01, 1.0),
    ) -> None:
        if max_in_flight < 1 or (endpoint.serial_port is not None and max_in_flight != 1):
            raise ParameterError(
                f"joint targets {endpoint}: max_in_flight must be 1 on a serial bus and >= 1, "
                f"got {max_in_flight}"
            )
        self.endpoint = endpoint
        self.max_in_flight = max_in_flight
        self._map = register_map or RegisterMap()
        self._framer = FramerRTU(DecodePDU(is_server=False))
        self._request = RequestFrame(self._map)
        self._request_bytes = self._request.frame.data  # a view: fill() shows through
        self._ack = FramerRTU(DecodePDU(is_server=True)).buildFrame(
            WriteMultipleRegistersResponse(
                address=self._map.start, count=self._map.count, dev_id=self._map.device_id
            )
        )
        self._timeout_ns = round(endpoint.timeout_s * 1e9)
        self._connect_timeout_ns = round(endpoint.connect_timeout_s * 1e9)
        self._backoff = Backoff(backoff_s)
        self._link: socket.socket | serial.Serial | None = None  # connecting or open
        self._fd = -1  # its descriptor once connected
        self._connect_started_ns = 0
        self._wanted = False  # between connect() and close(): poll reopens a lost link
        self._linked_before = False
        self._rx = bytearray()
        self._in_flight: deque[_Request] = deque()
        # the pending targets are in self._request.q_rad: (mode, submitted_ns, source_ns)
        self._pending: tuple[int, int, int] | None = None
        self._sequence = 0
        self.stats = WriterStats()
        self.errors = 0
        self.last_error: Exception | None = None

    def connect(self, *, timeout_s: float | None = 1.0) -> None:
        """Open the link; wait until it is open unless ``timeout_s`` is None.

        Raises LinkError if it is not open within ``timeout_s`` (with None, ``poll`` keeps
        trying with backoff).
        """
        if self._wanted:
            return
        self._wanted = True
        self._linked_before = False
        self._backoff.succeeded()
        self.poll(time.monotonic_ns())
        if timeout_s is None:
            return
        deadline_ns = time.monotonic_ns() + round(timeout_s * 1e9)
        while not self.is_connected:
            if time.monotonic_ns() >= deadline_ns:
                self.close()
                raise LinkError(
                    f"joint targets {self.endpoint}: cannot connect within {timeout_s} s "
                    f"({self.last_error or 'no answer'})"
                )
            wait_readable(-1, 0.002)
            self.poll(time.monotonic_ns())

    def close(self, *, flush_timeout_s: float = 0.0) -> None:
        """Close the link; poll no longer reopens it. Idempotent.

        With ``flush_timeout_s`` > 0, first polls (blocking) until the pending and in-flight
        writes are answered or that time has passed.
        """
        deadline_ns = time.monotonic_ns() + round(flush_timeout_s * 1e9)
        while self._fd >= 0 and (self._pending or self._in_flight):
            left_ns = deadline_ns - time.monotonic_ns()
            if left_ns <= 0:
                break
            wait_readable(self._fd, left_ns / 1e9)
            self.poll(time.monotonic_ns())
        self._wanted = False
        self._drop()

    @property
    def is_connected(self) -> bool:
        """True while the link is open."""
        return self._fd >= 0

    def fileno(self) -> int:
        """The socket's (or serial port's) descriptor to select on for replies; -1 while down."""
        return self._fd

    def write(self, value: ArrayLike, mode: Mode = Mode.TRACK, *, source_ns: int = 0) -> None:
        """Send the newest joint targets (6, rad) now, or keep them pending; never blocks.

        ``source_ns`` (monotonic) is when the input these targets answer arrived, e.g. the F/T
        frame; it comes back as ``stats.last_sent_source_ns`` once sent and
        ``stats.last_source_ns`` once acknowledged. Non-finite targets are refused (counted in
        ``stats.refused``), never sent.
        """
        request = self._request
        request.incoming[:] = value  # a copy: the caller may reuse its array
        stats = self.stats
        if not request.stage():  # the targets become the pending ones only if all finite
            stats.refused += 1
            return
        now_ns = time.monotonic_ns()
        stats.submitted += 1
        if self._pending is not None:
            stats.superseded += 1
        self._pending = (int(mode), now_ns, source_ns)
        try:
            self._send_pending()
        except Exception as err:  # whatever happens (even a bug), the caller's loop carries on
            self._fail(err, now_ns)

    def poll(self, now_ns: int) -> None:
        """Open the link when due, take replies, check timeouts, send the pending targets."""
        try:
            if self._fd < 0 and not self._link_up(now_ns):
                return
            self._take_replies(now_ns)
            if self._in_flight and now_ns - self._in_flight[0].sent_ns > self._timeout_ns:
                self.stats.timeouts += 1
                raise LinkError(
                    f"joint targets {self.endpoint}: no reply to write "
                    f"#{self._in_flight[0].sequence} within {self.endpoint.timeout_s} s"
                )
            self._send_pending()
        except Exception as err:  # whatever happens (even a bug), the caller's loop carries on
            self._fail(err, now_ns)

    def status(self) -> LinkStatus:
        """Link health; ``samples`` counts acknowledged writes, ``age_ns`` the last one's age."""
        last = self.stats.last_write_ns
        return LinkStatus(
            endpoint=str(self.endpoint),
            connected=self.is_connected,
            samples=self.stats.written,
            rate_hz=0.0,
            age_ns=None if last == 0 else time.monotonic_ns() - last,
            stalls=0,
            reconnects=self.stats.reconnects,
            errors=self.errors,
            last_error="" if self.last_error is None else error_text(self.last_error),
        )

    # -- requests and replies ----------------------------------------------------------------

    def _send_pending(self) -> None:
        pending = self._pending
        if pending is None or self._fd < 0 or len(self._in_flight) >= self.max_in_flight:
            return
        mode, submitted_ns, source_ns = pending
        sequence = (self._sequence + 1) & 0xFFFF
        self._request.fill_from_q(sequence, mode)
        if os.write(self._fd, self._request_bytes) != self._request_bytes.nbytes:
            raise LinkError(f"joint targets {self.endpoint}: send buffer full")
        sent_ns = time.monotonic_ns()
        self._sequence = sequence
        self._pending = None
        self._in_flight.append(_Request(sequence, submitted_ns, source_ns, sent_ns))
        stats = self.stats
        stats.sent += 1
        stats.in_flight = len(self._in_flight)
        stats.last_sent_ns = sent_ns
        stats.last_sent_source_ns = source_ns

    def _take_replies(self, now_ns: int) -> None:
        try:
            data = os.read(self._fd, READ_BYTES)
        except BlockingIOError:
            return
        if not data:
            if self.endpoint.serial_port is not None:
                return  # a tty set for timeout 0 reads b"" when empty
            raise LinkError(f"joint targets {self.endpoint}: closed by the robot")
        rx, ack = self._rx, self._ack
        rx += data
        while rx:
            if rx.startswith(ack):
                del rx[: len(ack)]
                self._answered(now_ns, None)
                continue
            size = rtu_frame_size(self._framer.decoder, rx)
            if size == 0:
                return  # the rest of a reply is still on its way
            try:
                _, reply = self._framer.handleFrame(bytes(rx[:size]), self._map.device_id, 0)
            except ModbusException:
                reply = None
            del rx[:size]
            if reply is None:
                self._error(ProtocolError(f"joint targets {self.endpoint}: garbled reply"))
            else:
                self._answered(now_ns, reply)

    def _answered(self, now_ns: int, reply: ModbusPDU | None) -> None:
        """The reply to the oldest request in flight: None for the acknowledgement."""
        if not self._in_flight:
            self._error(ProtocolError(f"joint targets {self.endpoint}: reply to no request"))
            return
        request = self._in_flight.popleft()
        stats = self.stats
        stats.in_flight = len(self._in_flight)
        if reply is None:
            stats.written += 1
            stats.last_write_ns = now_ns
            stats.last_latency_ns = now_ns - request.submitted_ns
            stats.last_source_ns = request.source_ns
        elif reply.isError():
            code = int(reply.exception_code)
            stats.exceptions[code] = stats.exceptions.get(code, 0) + 1
            name = ExcCodes(code).name if code in ExcCodes._value2member_map_ else "UNKNOWN"
            self._error(
                ModbusExceptionError(
                    code, name, f"write of joint targets #{request.sequence} to {self.endpoint}"
                )
            )
        else:
            self._error(
                ProtocolError(
                    f"joint targets {self.endpoint}: unexpected reply to #{request.sequence}: "
                    f"{type(reply).__name__}"
                )
            )

    # -- the link ----------------------------------------------------------------------------

    def _link_up(self, now_ns: int) -> bool:
        """Whether the link is open now: opens it when due, completes a TCP connect."""
        if self._link is None:
            if not (self._wanted and self._backoff.due(now_ns)):
                return False
            if self.endpoint.serial_port is not None:
                self._link = serial.Serial(
                    self.endpoint.serial_port, self.endpoint.baudrate, timeout=0
                )
            else:
                self._link = start_tcp_connect((self.endpoint.host, self.endpoint.port))
                self._connect_started_ns = now_ns
        link = self._link
        if isinstance(link, socket.socket) and not tcp_connected(link):
            if now_ns - self._connect_started_ns > self._connect_timeout_ns:
                raise LinkError(f"joint targets {self.endpoint}: connect timed out")
            return False
        self._fd = link.fileno()
        self._backoff.succeeded()
        if self._linked_before:
            self.stats.reconnects += 1
        self._linked_before = True
        return True

    def _error(self, err: Exception) -> None:
        self.errors += 1
        self.last_error = err

    def _fail(self, err: Exception, now_ns: int) -> None:
        """Count ``err``, drop the link and schedule its reopening."""
        self._error(err)
        self._drop()
        self._backoff.failed(now_ns)

    def _drop(self) -> None:
        link, self._link, self._fd = self._link, None, -1
        self._rx.clear()
        self._in_flight.clear()
        self.stats.in_flight = 0
        if link is not None:
            with contextlib.suppress(Exception):  # a broken link may fail to close too
                link.close()
