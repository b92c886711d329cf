"""The emulated Modbus endpoint answers pipelined requests, each in order, none lost."""

import socket

import numpy as np

from hilrig.drivers.joint_targets.frame import RequestFrame
from hilrig.drivers.joint_targets.wire import JointTargets, Mode, RegisterMap
from hilrig.emulator.modbus_server import EmulatedModbusServer

ACK_BYTES = 8  # device, function 16, address (2), count (2), CRC (2)


def test_requests_sent_in_one_segment_are_each_applied_and_answered() -> None:
    received: list[JointTargets] = []
    request = RequestFrame(RegisterMap())
    frames = b""
    for sequence in (1, 2, 3):
        request.fill(np.full(6, 0.1 * sequence), sequence, Mode.TRACK)
        frames += request.frame.tobytes()
    with (
        EmulatedModbusServer(
            lambda q_rad, sequence, mode: received.append(
                JointTargets(tuple(q_rad.tolist()), sequence, mode)
            )
        ) as server,
        socket.create_connection(("127.0.0.1", server.port), timeout=10) as client,
    ):
        client.sendall(frames)  # three requests before any reply
        replies = b""
        while len(replies) < 3 * ACK_BYTES:
            replies += client.recv(64)
    assert len(replies) == 3 * ACK_BYTES
    assert replies[:ACK_BYTES] == replies[ACK_BYTES : 2 * ACK_BYTES]  # identical acks
    assert [t.sequence for t in received] == [1, 2, 3]
    np.testing.assert_allclose([t.q_rad[0] for t in received], [0.1, 0.2, 0.3], rtol=1e-6)
    assert server.writes == 3
