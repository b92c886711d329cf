"""The emulated Modbus endpoint's fast path for whole-map writes answers exactly as pymodbus does.

Two servers on real loopback sockets, one with the fast path and one decoding every request with
pymodbus (``pymodbus_only=True``), get the same requests: well-formed writes, writes of unknown
modes, of another address, count or device, with a corrupted CRC, with injected exceptions, and
requests split across segments. Replies, counters and the targets applied must be identical.
"""

import socket
import struct
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ExceptionResponse
from pymodbus.pdu.register_message import (
    ReadHoldingRegistersRequest,
    WriteMultipleRegistersRequest,
    WriteMultipleRegistersResponse,
)

from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
from hilrig.emulator.modbus_server import EmulatedModbusServer, TargetsSink

MAP = RegisterMap()
FRAMER = FramerRTU(DecodePDU(is_server=False))
# the end of each exchange: a read request, which only ever gets ILLEGAL_FUNCTION (0x83)
MARKER = FRAMER.buildFrame(ReadHoldingRegistersRequest(address=0, count=1, dev_id=MAP.device_id))
MARKER_REPLY = FramerRTU(DecodePDU(is_server=True)).buildFrame(
    ExceptionResponse(0x03, ExcCodes.ILLEGAL_FUNCTION, MAP.device_id)
)


def collecting(applied: list[JointTargets]) -> TargetsSink:
    """A sink that keeps each write handed on, as the record it decodes to."""

    def take(q_rad: np.ndarray, sequence: int, mode: Mode) -> None:
        applied.append(JointTargets(tuple(q_rad.tolist()), sequence, mode))

    return take


@dataclass
class Peer:
    """A server, a connected client and what the server applied."""

    server: EmulatedModbusServer
    sock: socket.socket
    applied: list[JointTargets] = field(default_factory=list)
    fast_writes: int = 0


@pytest.fixture(scope="module")
def peers() -> Iterator[tuple[Peer, Peer]]:
    made = []
    for pymodbus_only in (False, True):
        applied: list[JointTargets] = []
        server = EmulatedModbusServer(collecting(applied), pymodbus_only=pymodbus_only).start()
        sock = socket.create_connection(("127.0.0.1", server.port), timeout=10)
        made.append(Peer(server, sock, applied))
    fast = made[0]
    answer = fast.server._answer_write

    def counted(client: object, reader: object, result: int) -> bytes:
        fast.fast_writes += 1
        return answer(client, reader, result)  # type: ignore[arg-type]

    fast.server._answer_write = counted  # type: ignore[method-assign]
    yield made[0], made[1]
    for peer in made:
        peer.sock.close()
        peer.server.stop()


def exchange(peer: Peer, pieces: list[bytes]) -> bytes:
    """Send ``pieces`` (one ``sendall`` each), then the marker; the replies before the
    marker's."""
    for piece in pieces:
        peer.sock.sendall(piece)
    peer.sock.sendall(MARKER)
    replies = b""
    while not replies.endswith(MARKER_REPLY):
        replies += peer.sock.recv(4096)
    return replies.removesuffix(MARKER_REPLY)


registers = st.lists(st.integers(0, 0xFFFF), min_size=MAP.count, max_size=MAP.count)


@st.composite
def requests(draw: st.DrawFn) -> bytes:
    """A function-16 request: mostly whole-map writes, some off the map or corrupted."""
    values = draw(registers)
    if draw(st.booleans()):  # a known mode, so that most writes apply
        values[MAP.mode[0] - MAP.start] = draw(st.integers(0, 2))
    address = draw(st.sampled_from([MAP.start, MAP.start, MAP.start + 1]))
    dev_id = draw(st.sampled_from([MAP.device_id, MAP.device_id, MAP.device_id + 1]))
    count = draw(st.sampled_from([MAP.count, MAP.count, MAP.count - 1]))
    frame = bytearray(
        FRAMER.buildFrame(
            WriteMultipleRegistersRequest(address=address, registers=values[:count], dev_id=dev_id)
        )
    )
    if draw(st.integers(0, 4)) == 0:  # a corrupted byte after the header: the CRC fails
        at = draw(st.integers(7, len(frame) - 1))
        frame[at] ^= draw(st.integers(1, 255))
    return bytes(frame)


def whole_map_write(sequence: int) -> bytes:
    """A valid write of the whole map (TRACK, every target 0.25 rad)."""
    values = [0] * MAP.count
    at = MAP.targets[0] - MAP.start
    values[at : at + 12] = struct.unpack(">12H", struct.pack(">6f", *([0.25] * 6)))
    values[MAP.sequence[0] - MAP.start] = sequence
    values[MAP.mode[0] - MAP.start] = 1
    request = WriteMultipleRegistersRequest(
        address=MAP.start, registers=values, dev_id=MAP.device_id
    )
    return FRAMER.buildFrame(request)


@settings(max_examples=150, deadline=None)
@given(
    frames=st.lists(requests(), min_size=1, max_size=4),
    cut=st.integers(0, 40),
    injected=st.integers(0, 2),
)
def test_fast_path_replies_and_applies_exactly_as_pymodbus(
    peers: tuple[Peer, Peer], frames: list[bytes], cut: int, injected: int
) -> None:
    stream = b"".join(frames)
    pieces = [stream[:cut], stream[cut:]] if 0 < cut < len(stream) else [stream]
    outcomes = []
    for peer in peers:
        peer.server.inject_exceptions(injected, ExcCodes.DEVICE_BUSY)  # 0 clears what is left
        before = len(peer.applied)
        replies = exchange(peer, pieces)
        server = peer.server
        counters = (server.writes, server.rejected, server.exceptions_sent)
        outcomes.append((replies, counters, peer.applied[before:]))
    assert outcomes[0] == outcomes[1]


def test_whole_map_writes_take_the_fast_path(peers: tuple[Peer, Peer]) -> None:
    ack = FramerRTU(DecodePDU(is_server=True)).buildFrame(
        WriteMultipleRegistersResponse(address=MAP.start, count=MAP.count, dev_id=MAP.device_id)
    )
    fast, reference = peers
    before = fast.fast_writes
    for peer in peers:
        peer.server.inject_exceptions(0)
        writes = [whole_map_write(sequence) for sequence in (1, 2, 3)]
        assert exchange(peer, writes) == 3 * ack
    assert fast.fast_writes == before + 3
    assert [t.sequence for t in fast.applied[-3:]] == [1, 2, 3]
    assert fast.applied[-3:] == reference.applied[-3:]


def test_non_finite_targets_are_refused_with_illegal_value(peers: tuple[Peer, Peer]) -> None:
    refused = FramerRTU(DecodePDU(is_server=True)).buildFrame(
        ExceptionResponse(0x10, ExcCodes.ILLEGAL_VALUE, MAP.device_id)
    )
    nan_write = bytearray(whole_map_write(7))
    at = 7 + 2 * (MAP.targets[0] - MAP.start)  # the first target's two registers
    nan_write[at : at + 4] = struct.pack(">f", float("nan"))
    nan_write[-2:] = FRAMER.compute_CRC(bytes(nan_write[:-2])).to_bytes(2, "big")
    for peer in peers:
        peer.server.inject_exceptions(0)
        applied, rejected = len(peer.applied), peer.server.rejected
        assert exchange(peer, [bytes(nan_write)]) == refused
        assert len(peer.applied) == applied and peer.server.rejected == rejected + 1


WARM_CHILD = """
import socket, struct
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.register_message import WriteMultipleRegistersRequest
from hilrig.drivers.joint_targets.frame import crc16, read_request
from hilrig.drivers.joint_targets.wire import RegisterMap
from hilrig.emulator.modbus_server import EmulatedModbusServer
MAP = RegisterMap()
values = [0] * MAP.count
values[MAP.mode[0] - MAP.start] = 1
request = FramerRTU(DecodePDU(is_server=False)).buildFrame(
    WriteMultipleRegistersRequest(address=MAP.start, registers=values, dev_id=MAP.device_id)
)
applied = []
server = EmulatedModbusServer(lambda *write: applied.append(write)).start()
ready = (len(read_request.signatures), len(crc16.signatures))
with socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
    sock.sendall(request)
    sock.recv(64)
server.stop()
print(*ready, len(read_request.signatures), len(crc16.signatures), len(applied))
"""


def test_the_request_kernel_is_ready_before_the_first_request() -> None:
    """In a process of its own: the endpoint loads its compiled request reader (and CRC), for
    the type requests arrive in, when it is made; the first write over a real socket (applied)
    adds no signature, so it does not stop the rig's slots while numba loads or compiles one."""
    out = subprocess.run(
        [sys.executable, "-c", WARM_CHILD], capture_output=True, text=True, check=True
    ).stdout.split()
    read_before, crc_before, read_after, crc_after, applied = map(int, out)
    assert (read_before, read_after, crc_after, applied) == (1, 1, crc_before, 1)
