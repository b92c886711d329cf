"""Joint targets over Modbus RTU framing on a real loopback socket, against the emulator."""

import struct
import threading
from collections.abc import Iterator

import pytest
from pymodbus.constants import ExcCodes
from waiting import wait_until

from hilrig.drivers.emulated.modbus_server import EmulatedModbusServer
from hilrig.drivers.joint_targets import JointTargetsWriter, ModbusEndpoint
from hilrig.drivers.joint_targets_map import JointTargets, Mode, RegisterMap
from hilrig.errors import LinkError, ModbusExceptionError


class Received:
    def __init__(self) -> None:
        self.targets: list[JointTargets] = []
        self.lock = threading.Lock()

    def __call__(self, targets: JointTargets) -> None:
        with self.lock:
            self.targets.append(targets)


@pytest.fixture
def server() -> Iterator[tuple[EmulatedModbusServer, Received]]:
    received = Received()
    with EmulatedModbusServer(received) as srv:
        yield srv, received


def f32(values: tuple[float, ...]) -> tuple[float, ...]:
    return struct.unpack("6f", struct.pack("6f", *values))


def test_register_map_round_trip() -> None:
    register_map = RegisterMap()
    targets = JointTargets(f32((0.1, -1.2, 2.3, -3.0, 0.0, 1.5)), 65535, Mode.TRACK)
    registers = register_map.encode(targets)
    assert len(registers) == register_map.count == 14
    assert registers[12:] == [65535, 1]
    assert register_map.decode(registers) == targets
    with pytest.raises(ValueError, match="must be 6 finite values"):
        register_map.encode(JointTargets((float("nan"),) * 6, 0, Mode.HOLD))


def test_targets_reach_the_robot(server: tuple[EmulatedModbusServer, Received]) -> None:
    srv, received = server
    q = (0.1, -0.2, 0.3, -0.4, 0.5, -0.6)
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        writer.write(q)
        wait_until(lambda: writer.stats.written == 1)
    assert received.targets == [JointTargets(f32(q), 1, Mode.TRACK)]
    assert writer.stats.last_latency_ns > 0


def test_each_write_carries_a_new_watchdog_count(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, received = server
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for n in range(20):
            writer.write([0.01 * n] * 6)
            wait_until(lambda n=n: writer.stats.written == n + 1)
    assert [t.sequence for t in received.targets] == list(range(1, 21))


def test_non_finite_targets_are_never_sent(server: tuple[EmulatedModbusServer, Received]) -> None:
    srv, received = server
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        writer.write([float("inf")] + [0.0] * 5)
        writer.write([0.0] * 6)
        wait_until(lambda: writer.stats.written == 1)
    assert writer.stats.refused == 1
    assert len(received.targets) == 1


def test_modbus_exceptions_are_typed_and_counted(
    server: tuple[EmulatedModbusServer, Received],
) -> None:
    srv, received = server
    srv.inject_exceptions(2, ExcCodes.DEVICE_BUSY)
    with JointTargetsWriter(ModbusEndpoint(port=srv.port)) as writer:
        for _ in range(3):
            seen = writer.stats.written + sum(writer.stats.exceptions.values())
            writer.write([0.0] * 6)
            wait_until(
                lambda seen=seen: (
                    writer.stats.written + sum(writer.stats.exceptions.values()) > seen
                )
            )
    assert writer.stats.exceptions == {int(ExcCodes.DEVICE_BUSY): 2}
    assert writer.stats.written == 1 and len(received.targets) == 1
    assert isinstance(writer.last_error, ModbusExceptionError)
    assert str(writer.last_error) == (
        f"Modbus exception 6 (DEVICE_BUSY) in reply to write of joint targets #2 to "
        f"rtu+tcp://127.0.0.1:{srv.port}"
    )


def test_writer_reconnects_after_the_link_drops() -> None:
    received = Received()
    first = EmulatedModbusServer(received)
    first.start()
    port = first.port
    with JointTargetsWriter(ModbusEndpoint(port=port), backoff_s=(0.005, 0.05)) as writer:
        writer.write([0.0] * 6)
        wait_until(lambda: writer.stats.written == 1)
        first.stop()
        writer.write([0.1] * 6)
        wait_until(lambda: writer.stats.reconnects >= 1)
        with EmulatedModbusServer(received, port=port):
            wait_until(lambda: writer.is_connected)
            writer.write([0.2] * 6)
            wait_until(lambda: writer.stats.written == 2)
    assert received.targets[-1].q_rad == f32((0.2,) * 6)


def test_connect_fails_clearly_when_no_robot_listens() -> None:
    with EmulatedModbusServer(Received()) as srv:
        port = srv.port
    writer = JointTargetsWriter(ModbusEndpoint(port=port))
    with pytest.raises(LinkError) as err:
        writer.connect(timeout_s=0.2)
    assert str(err.value) == f"cannot connect to Modbus rtu+tcp://127.0.0.1:{port} within 0.2 s"
    assert not writer.is_connected
