"""The one place that chooses a session's robot link; the loop sees only its shape
(:mod:`.robot_port`).

- ``arcs``: an AUBO controller running ARCS, through AUBO's own client (pyaubo-sdk): joint
  states over RTDE, ``servoJoint`` over JSON-RPC at the servo rate, in a process of its own
  (:mod:`hilrig.rig.arcs`). A real AUBO-i5 speaks it, and so does the emulated rig.
- ``modbus``: a joint-state TCP stream (HRS1) and a Modbus joint-target register map, polled on
  the loop's thread: for a controller commanded over Modbus registers, as in the paper's setup
  (docs/protocols.md); the emulated rig speaks it too.

Adding a robot means a new kind here and a link of that shape, never a change to the loop.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, replace

from hilrig.emulator.rig import RigEndpoints
from hilrig.errors import LinkError
from hilrig.rig.arcs.settings import ArcsSettings
from hilrig.rig.kinds import RobotLinkKind
from hilrig.rig.rings import Ring
from hilrig.rig.robot_port import JointStateSource, JointTargetSink

MODBUS_STATE_PERIOD_NS = 1_000_000  # the HRS1 stream sends a state every 1 ms slot


@dataclass
class RobotLink:
    """A connected robot link: what the loop polls and writes, and the session's hooks.

    ``arm()`` readies the robot to follow targets (servo mode), once the first state is in,
    and ``disarm()`` ends that (the states stream on; the link's close does it too);
    ``fault_fd`` is readable when ``fault()`` may have a reason to end the session (-1: never);
    ``state_period_ns`` is how often a joint state comes (the loop's staleness follows it);
    ``describe`` is what the session's record says of the link, ``figures()`` what the link
    did (read once it is closed), ``record_into(ring)`` passes what was sent to the robot on to
    the recorder (the servo calls; nothing for a link that sends every tick's targets).
    """

    states: JointStateSource
    targets: JointTargetSink
    arm: Callable[[], None]
    disarm: Callable[[], None]
    fault: Callable[[], str]
    fault_fd: int
    state_period_ns: int
    describe: dict[str, object]
    figures: Callable[[], dict[str, object]]
    record_into: Callable[[Ring], None]


def open_robot_link(
    stack: ExitStack,
    kind: RobotLinkKind,
    endpoints: RigEndpoints,
    arcs: ArcsSettings | None,
) -> RobotLink:
    """Connect the robot link of ``kind`` (closed by ``stack``); raises LinkError (one line).

    ``arcs`` sets the ARCS link's user, password and servo stream; its host and ports are the
    ``endpoints``' ``aubo_rpc`` and ``aubo_rtde``.
    """
    if kind is RobotLinkKind.ARCS:
        if not endpoints.aubo_rpc[0]:
            raise LinkError("robot link arcs: no AUBO controller (its host) among the endpoints")
        return _arcs(stack, endpoints, arcs or ArcsSettings())
    return _modbus(stack, endpoints)


def _arcs(stack: ExitStack, endpoints: RigEndpoints, settings: ArcsSettings) -> RobotLink:
    from hilrig.rig.arcs.link import ArcsJointStates, ArcsLink, ArcsTargets

    (host, rpc_port), (_, rtde_port) = endpoints.aubo_rpc, endpoints.aubo_rtde
    settings = replace(settings, host=host, rpc_port=rpc_port, rtde_port=rtde_port)
    link = ArcsLink(settings)
    stack.callback(link.stop)
    info = link.start()
    targets = ArcsTargets(link)
    return RobotLink(
        ArcsJointStates(link),
        targets,
        link.servo_on,
        link.servo_off,
        link.fault,
        link.fileno,
        settings.rtde_period_ns,
        {
            "robot_link": RobotLinkKind.ARCS.value,
            "controller": settings.where(),
            "servo_rate_hz": settings.servo_rate_hz,
            "servo_lookahead_s": settings.lookahead_s,
            "servo_gain": settings.gain,
            "rtde_rate_hz": settings.rtde_rate_hz,
            **{f"arcs_{key}": value for key, value in info.items()},
        },
        lambda: link.figures,
        targets.record_into,
    )


def _modbus(stack: ExitStack, endpoints: RigEndpoints) -> RobotLink:
    from hilrig.drivers.joint_targets.link import JointTargetsWriter, ModbusEndpoint
    from hilrig.drivers.robot_state.link import RobotStateClient

    if not (endpoints.robot_state[0] and endpoints.modbus[0]):
        raise LinkError("robot link modbus: no robot_state and modbus endpoints ([endpoints])")
    robot = RobotStateClient(*endpoints.robot_state)
    # two requests in flight: a reply is read at the next tick, and TCP keeps them in order
    targets = JointTargetsWriter(ModbusEndpoint(*endpoints.modbus), max_in_flight=2)
    robot.connect(first_frame_timeout_s=None)
    stack.callback(robot.close)
    targets.connect()
    stack.callback(targets.close)
    return RobotLink(
        robot,
        targets,
        lambda: None,
        lambda: None,
        lambda: "",
        -1,
        MODBUS_STATE_PERIOD_NS,
        {"robot_link": RobotLinkKind.MODBUS.value},
        dict,
        lambda ring: None,
    )
