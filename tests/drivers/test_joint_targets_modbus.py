"""Joint targets over Modbus RTU framing, polled from the test thread: real loopback sockets and
a real pty against the emulated robot's pymodbus server or a peer speaking pymodbus frames.

Waits poll until a count is reached, with a generous deadline; nothing asserts on timing.
"""

import contextlib
import os
import socket
import struct
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from polling import poll_for, poll_until
from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.exceptionresponse import ExceptionResponse
from pymodbus.pdu.register_message import (
    WriteMultipleRegistersRequest,
    WriteMultipleRegistersResponse,
)

from hilrig.drivers.joint_targets.link import JointTargetsWriter, ModbusEndpoint
from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
from hilrig.emulator.modbus_server import EmulatedModbusServer
from hilrig.errors import (
    DriverError,
    LinkError,
    ModbusExceptionError,
    ParameterError,
    ProtocolError,
)

MAP = RegisterMap()
REQUEST_BYTES = 9 + 2 * MAP.count  # device id, function, address, count, byte count, CRC


class Received:
    def __init__(self) -> None:
        self.targets: list[JointTargets] = []
        self.lock = threading.Lock()

    def __call__(self, q_rad: np.ndarray, sequence: int, mode: Mode) -> None:
        with self.lock:
            self.targets.append(JointTargets(tuple(q_rad.tolist()), sequence, mode))


@pytest.fixture
def server() -> Iterator[tuple[EmulatedModbusServer, Received]]:
    received = Received()
    with EmulatedModbusServer(received) as srv:
        yield srv, received


def f32(values: tuple[float, ...]) -> tuple[float, ...]:
    return struct.unpack("6f", struct.pack("6f", *values))


def answered(writer: JointTargetsWriter) -> int:
    return writer.stats.written + sum(writer.stats.exceptions.values())


def server_frame(reply: WriteMultipleRegistersResponse | ExceptionResponse) -> bytes:
    return FramerRTU(DecodePDU(is_server=True)).buildFrame(reply)


def ack(register_map: RegisterMap = MAP) -> bytes:
    return server_frame(
        WriteMultipleRegistersResponse(
            address=register_map.start, count=register_map.count, dev_id=register_map.device_id
        )
    )


def read_request(fd: int) -> JointTargets:
    """One request from the writer, decoded by pymodbus's server framer."""
    os.set_blocking(fd, False)
    data = b""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        with contextlib.suppress(BlockingIOError):
            data += os.read(fd, REQUEST_BYTES - len(data))
        used, request = FramerRTU(DecodePDU(is_server=True)).handleFrame(data, 0, 0)
        if request is not None:
            assert isinstance(request, WriteMultipleRegistersRequest) and used == len(data)
            return MAP.decode(list(request.registers))
        time.sleep(0.001)
    raise AssertionError(f"no request within 10 s, got {data.hex()}")


def test_register_map_round_trip() -> None:
    targets = JointTargets(f32((0.1, -1.2, 2.3, -3.0, 0.0, 1.5)), 65535, Mode.TRACK)
    registers = MAP.encode(targets)
    assert len(registers) == MAP.count == 14
    assert registers[12:] == [65535, 1]
    assert MAP.decode(registers) == targets
    nan = JointTargets((float("nan"),) * 6, 0, Mode.HOLD)
    with pytest.raises(DriverError) as err:
        MAP.encode(nan)
    assert (
        str(err.value)
        == "joint targets must be 6 finite values, got (nan, nan, nan, nan, nan, nan)"
    )
    with pytest.raises(ProtocolError) as err:
        MAP.decode([*registers[:13], 7])
    assert str(err.value) == "joint targets: unknown mode 7"


@settings(deadline=None)  # the first example loads the request kernel
@given(
    start=st.integers(0, 1000),
    device_id=st.integers(1, 247),
)
def test_the_expected_acknowledgement_is_what_pymodbus_decodes(start: int, device_id: int) -> None:
    register_map = RegisterMap((start, 12), (start + 12, 1), (start + 13, 1), device_id)
    writer = JointTargetsWriter(ModbusEndpoint(), register_map=register_map)
    used, reply = FramerRTU(DecodePDU(is_server=False)).handleFrame(writer._ack, device_id, 0)
    assert used == len(writer._ack) and isinstance(reply, WriteMultipleRegistersResponse)
    assert (reply.dev_id, reply.address, reply.count) == (device_id, start, 14)


def test_targets_reach_the_robot(server: tuple[EmulatedModbusServer, Received]) -> None:
    srv, received = server
    q = (0.1, -0.2, 0.3, -0.4, 0.5, -0.6)
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        writer.write(q, source_ns=42)
        assert writer.stats.sent == writer.stats.in_flight == 1  # sent at once
        assert writer.stats.last_sent_source_ns == 42 and writer.stats.last_source_ns == 0
        poll_until(lambda: writer.stats.written == 1, writer)
        assert writer.stats.in_flight == 0 and writer.stats.last_source_ns == 42
    assert received.targets == [JointTargets(f32(q), 1, Mode.TRACK)]
    assert writer.errors == 0 and writer.fileno() == -1


def test_each_write_carries_a_new_watchdog_count(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, received = server
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for n in range(20):
            writer.write([0.01 * n] * 6)
            poll_until(lambda n=n: writer.stats.written == n + 1, writer)
    assert [t.sequence for t in received.targets] == list(range(1, 21))
    assert writer.stats.superseded == 0 and writer.stats.sent == 20


def test_a_busy_slot_keeps_only_the_newest_targets(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, received = server
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for n in range(5):  # no poll in between: one in flight, the rest supersede each other
            writer.write([0.1 * n] * 6, source_ns=n)
        assert writer.stats.sent == 1 and writer.stats.superseded == 3
        poll_until(lambda: writer.stats.written == 2, writer)
        assert writer.stats.last_source_ns == 4
    assert received.targets == [
        JointTargets(f32((0.0,) * 6), 1, Mode.TRACK),
        JointTargets(f32((0.4,) * 6), 2, Mode.TRACK),
    ]


def test_several_requests_in_flight_are_answered_in_order() -> None:
    # a socket peer: the emulator's pymodbus server takes one request at a time, as RTU expects
    with socket.create_server(("127.0.0.1", 0)) as listener:
        writer = JointTargetsWriter(ModbusEndpoint(port=listener.getsockname()[1]), max_in_flight=3)
        writer.connect(timeout_s=None)
        peer, _ = listener.accept()
        with peer:
            poll_until(lambda: writer.is_connected, writer)
            for n in range(4):
                writer.write([0.1 * n] * 6, source_ns=n)
            assert writer.stats.sent == writer.stats.in_flight == 3
            assert [read_request(peer.fileno()).sequence for _ in range(3)] == [1, 2, 3]
            peer.sendall(ack() + server_frame(ExceptionResponse(16, 6)) + ack())  # one segment
            poll_until(lambda: writer.stats.sent == 4, writer)
            assert writer.stats.written == 2 and writer.stats.exceptions == {6: 1}
            assert writer.stats.last_source_ns == 2
            assert "#2" in str(writer.last_error)
            assert read_request(peer.fileno()).sequence == 4
        writer.close()
    assert writer.errors == 1 and writer.stats.superseded == 0


def test_no_thread_runs_while_writing_and_polling(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, _ = server
    before = threading.active_count()
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for n in range(30):
            writer.write([0.0] * 6)
            poll_until(lambda n=n: writer.stats.written == n + 1, writer)
            assert threading.active_count() == before


def test_non_finite_targets_are_never_sent(server: tuple[EmulatedModbusServer, Received]) -> None:
    srv, received = server
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        writer.write([float("inf")] + [0.0] * 5)
        writer.write([0.0] * 6)
        poll_until(lambda: writer.stats.written == 1, writer)
    assert writer.stats.refused == 1 and writer.stats.sent == 1
    assert len(received.targets) == 1


def test_modbus_exceptions_are_typed_and_counted(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, received = server
    srv.inject_exceptions(2, ExcCodes.DEVICE_BUSY)
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for n in range(3):
            writer.write([0.0] * 6)
            poll_until(lambda n=n: answered(writer) == n + 1, writer)
    assert writer.stats.exceptions == {int(ExcCodes.DEVICE_BUSY): 2}
    assert writer.stats.written == 1 and len(received.targets) == 1
    assert isinstance(writer.last_error, ModbusExceptionError)
    assert str(writer.last_error) == (
        f"Modbus exception 6 (DEVICE_BUSY) in reply to write of joint targets #2 to "
        f"rtu+tcp://127.0.0.1:{srv.port}"
    )
    assert writer.stats.reconnects == 0  # an exception reply is no reason to drop the link


def test_replies_in_pieces_garbage_and_timeouts_from_a_socket_peer() -> None:
    with socket.create_server(("127.0.0.1", 0)) as listener:
        port = listener.getsockname()[1]
        endpoint = ModbusEndpoint(port=port, timeout_s=0.2)
        writer = JointTargetsWriter(endpoint, backoff_s=(0.005, 0.02))
        writer.connect(timeout_s=None)
        peer, _ = listener.accept()
        with peer:
            poll_until(lambda: writer.is_connected, writer)
            writer.write([0.5] * 6)
            assert read_request(peer.fileno()).sequence == 1
            reply = ack()
            peer.sendall(reply[:3])
            poll_for(0.01, writer)
            peer.sendall(reply[3:])
            poll_until(lambda: writer.stats.written == 1, writer)
            writer.write([0.6] * 6)
            assert read_request(peer.fileno()).sequence == 2
            peer.sendall(server_frame(ExceptionResponse(16, 4)))
            poll_until(lambda: writer.stats.exceptions == {4: 1}, writer)
            assert str(writer.last_error).startswith("Modbus exception 4 (DEVICE_FAILURE)")
            writer.write([0.7] * 6)
            assert read_request(peer.fileno()).sequence == 3
            peer.sendall(b"\x01\x10\xff\xff\xff\xff\x00\x00")  # a bad CRC
            poll_until(lambda: writer.stats.timeouts == 1, writer)
        assert str(writer.last_error) == (
            f"joint targets rtu+tcp://127.0.0.1:{port}: no reply to write #3 within 0.2 s"
        )
        assert writer.errors == 3  # the exception, the garbled reply, the timeout
        poll_until(lambda: writer.is_connected, writer)  # the listener's backlog took it
        assert writer.stats.reconnects == 1
        writer.close()
    assert writer.stats.written == 1 and writer.stats.sent == 3


def test_writer_reconnects_after_the_link_drops() -> None:
    received = Received()
    first = EmulatedModbusServer(received)
    first.start()
    port = first.port
    with JointTargetsWriter(ModbusEndpoint(port=port), backoff_s=(0.005, 0.05)) as writer:
        writer.write([0.0] * 6)
        poll_until(lambda: writer.stats.written == 1, writer)
        first.stop()
        writer.write([0.1] * 6)
        poll_until(lambda: writer.errors >= 2 and not writer.is_connected, writer)
        with EmulatedModbusServer(received, port=port):
            poll_until(lambda: writer.is_connected, writer)
            assert writer.stats.reconnects == 1
            writer.write([0.2] * 6)
            poll_until(lambda: writer.stats.written == 2, writer)
    assert received.targets[-1].q_rad == f32((0.2,) * 6)


def test_connect_fails_clearly_when_no_robot_listens() -> None:
    with EmulatedModbusServer(Received()) as srv:
        port = srv.port
    writer = JointTargetsWriter(ModbusEndpoint(port=port))
    with pytest.raises(LinkError) as err:
        writer.connect(timeout_s=0.2)
    assert str(err.value) == (
        f"joint targets rtu+tcp://127.0.0.1:{port}: cannot connect within 0.2 s "
        "(TCP connect failed: Connection refused)"
    )
    assert not writer.is_connected


def test_targets_over_a_serial_pty() -> None:
    master, slave = os.openpty()
    try:
        os.set_blocking(master, False)
        endpoint = ModbusEndpoint(serial_port=os.ttyname(slave))
        with pytest.raises(ParameterError, match="max_in_flight must be 1 on a serial bus"):
            JointTargetsWriter(endpoint, max_in_flight=2)
        with JointTargetsWriter(endpoint) as writer:
            for n in range(3):
                writer.write([0.1 * n] * 6, Mode.HOLD)
                assert read_request(master) == JointTargets(f32((0.1 * n,) * 6), n + 1, Mode.HOLD)
                os.write(master, ack())
                poll_until(lambda n=n: writer.stats.written == n + 1, writer)
        assert writer.errors == 0
    finally:
        os.close(master)
        os.close(slave)
