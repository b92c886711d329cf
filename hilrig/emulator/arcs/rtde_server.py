"""The emulated controller's RTDE port (a real one's TCP 30010), a device of the slot loop.

On connect the server sends its hello (wire.py: protocol "1", version 1, the input and output
maps below). A client then asks for topics with a CBOR message ``[100, {"chanel": c,
"frequency": f, "segments": [names], "to_server": false, "trigger": t}]`` (``trigger`` is not
initialised by every 0.24.1 call: ignored); the same chanel again replaces its topic, and
``removeTopic`` sends it with frequency 0 and no segments. Each topic is then pushed as
``[c, value, ...]`` in its names' order, on the slots where its phase passes a whole period: the
slot index k since the controller started, the sample index ``k * f // rate``; a new sample
index means a push (200 Hz: every 5th 1 ms slot, 500 Hz: every 2nd). A slot the loop skipped
is a sample not sent. A topic of a frequency <= 0 or above the slot rate, or with a name not
in the output map, is refused (counted; nothing is pushed; the client, which sent it without
waiting, is not told: 0.24.1 checks names against the hello itself and returns -1 before
sending). Input topics (``to_server``) and their data are taken and ignored.

0.24.1's ``RtdeClient.login`` sends nothing (the login is the client's own bookkeeping); a
``__login__`` text in an RTDE frame, should a client send one, is answered ``SUCCEED`` or
``FAILED`` (then closed) like the RPC port's.

Outputs (ids in the order of AUBO's rtde_recipe documentation, R1_message = 1000; ``timestamp``
0): ``timestamp`` is a double, the slot's deadline in seconds since the controller started
(AUBO: "Time elapsed since the controller was started [s]"), so a reader recovers the slot index
exactly; joint values are the plant's (q, qd), the last accepted servoJoint's q (target), the
joint torque sensors (the scenario's torques plus the HRS1 stream's noise of the same slot)
and the currents (torque over a torque constant per joint, controller.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cbor2

from hilrig.emulator.arcs.controller import ArcsController
from hilrig.emulator.arcs.links import LinkServer
from hilrig.emulator.arcs.wire import (
    LOGIN_FAILED,
    LOGIN_SUCCEED,
    FrameDecoder,
    parse_login,
    rtde_frame,
    rtde_hello,
)

SET_TOPIC = 100  # the first element of a setTopic message

Getter = Callable[[ArcsController], object]
OUTPUTS: dict[str, tuple[int, Getter]] = {
    "timestamp": (0, lambda arcs: arcs.time_s),
    "R1_target_q": (1001, lambda arcs: arcs.target_q_rad.tolist()),
    "R1_actual_q": (1006, lambda arcs: arcs.q_rad.tolist()),
    "R1_actual_qd": (1007, lambda arcs: arcs.qd_rad_s.tolist()),
    "R1_actual_current": (1008, lambda arcs: arcs.current_a.tolist()),
    "R1_robot_mode": (1014, lambda arcs: arcs.robot_mode.name),
    "R1_safety_mode": (1015, lambda arcs: arcs.safety_mode.name),
    "R1_joint_torque_sensor": (1034, lambda arcs: arcs.torque_nm.tolist()),
}
INPUTS: dict[str, int] = {}  # no input is served


@dataclass
class Topic:
    """One client's output topic."""

    chanel: int
    frequency_mhz: int  # the frequency in mHz (integer phase arithmetic)
    getters: tuple[Getter, ...]
    last_index: int  # sample index of the last push (or of the slot it was set in)


class EmulatedArcsRtdeServer(LinkServer):
    """ARCS's RTDE server over the emulated controller ``arcs``, pushing at ``rate_hz`` slots."""

    thread_name = "arcs-rtde"

    def __init__(
        self,
        arcs: ArcsController,
        *,
        rate_hz: float = 1000.0,
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        super().__init__(host, port)
        self._arcs = arcs
        self._rate_mhz = round(rate_hz * 1000)
        self.standalone_period_ns = round(1e9 / rate_hz)
        self._hello = rtde_hello({name: oid for name, (oid, _) in OUTPUTS.items()}, INPUTS)
        self._epoch = arcs.link_epoch
        self._topics: dict[int, dict[int, Topic]] = {}  # per client fd: chanel -> topic
        self._t0_ns: int | None = None
        self._period_ns = self.standalone_period_ns
        self._slot_index = 0  # the last slot's, since the controller started
        self.topics_set = 0
        self.topics_refused = 0
        self.messages_ignored = 0  # input data, unknown messages, undecodable bodies

    def tick(self, slot_ns: int) -> None:
        """Close every client after a drop_links fault; push the topics due in this slot."""
        arcs = self._arcs
        if arcs.link_epoch != self._epoch:
            self._epoch = arcs.link_epoch
            self.drop_all()
        if self._t0_ns is None:
            loop = self._require_loop()
            self._t0_ns, self._period_ns = loop.t0_ns, loop.period_ns
        self._slot_index = slot_index = (slot_ns - self._t0_ns) // self._period_ns
        if arcs.rtde_stalled or not self._topics:
            return
        rate = self._rate_mhz
        for fd, topics in list(self._topics.items()):
            for topic in list(topics.values()):
                index = slot_index * topic.frequency_mhz // rate
                if index == topic.last_index:
                    continue
                topic.last_index = index
                message: list[object] = [topic.chanel]
                message += [getter(arcs) for getter in topic.getters]
                self.send(fd, rtde_frame(cbor2.dumps(message)))
                if fd not in self.links:
                    break

    def _decoder(self) -> FrameDecoder:
        return FrameDecoder.rtde()

    def _greet(self, fd: int) -> None:
        self._topics[fd] = {}
        self.send(fd, self._hello, frame=False)

    def _received(self, fd: int, body: bytes) -> None:
        if body.startswith(b"__login__"):
            login = parse_login(body)
            ok = login is not None and self._arcs.login(login.user, login.token)
            self.send(fd, rtde_frame(LOGIN_SUCCEED if ok else LOGIN_FAILED), frame=False)
            self.links[fd].closing = not ok
            return
        try:
            message = cbor2.loads(body)
        except Exception:  # cbor2 raises several kinds on malformed input
            message = None
        if (
            isinstance(message, list)
            and len(message) == 2
            and message[0] == SET_TOPIC
            and isinstance(message[1], dict)
        ):
            self._set_topic(fd, message[1])
        else:
            self.messages_ignored += 1

    def _set_topic(self, fd: int, spec: dict[object, object]) -> None:
        chanel, frequency = spec.get("chanel"), spec.get("frequency")
        names = spec.get("segments")
        if not isinstance(chanel, int) or not isinstance(names, list):
            self.topics_refused += 1
            return
        topics = self._topics[fd]
        topics.pop(chanel, None)
        if spec.get("to_server"):
            self.messages_ignored += 1  # an input topic: taken, nothing served
            return
        if not names:  # removeTopic
            return
        rate_hz = self._rate_mhz / 1000
        if (
            not isinstance(frequency, int | float)
            or not math.isfinite(frequency)
            or not 0 < frequency <= rate_hz
            or not all(isinstance(name, str) and name in OUTPUTS for name in names)
        ):
            self.topics_refused += 1
            return
        getters = tuple(OUTPUTS[name][1] for name in names if isinstance(name, str))
        frequency_mhz = round(frequency * 1000)
        # the first push at the topic's next period boundary, not at once
        index = self._slot_index * frequency_mhz // self._rate_mhz
        topics[chanel] = Topic(chanel, frequency_mhz, getters, last_index=index)
        self.topics_set += 1

    def _close(self, fd: int) -> None:
        self._topics.pop(fd, None)
        super()._close(fd)
