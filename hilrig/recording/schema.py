"""What a hilrig session records: topics, their ROS 2 message types and channel metadata.

Standard ROS 2 types are used where one exists (WrenchStamped, JointState, PoseStamped); the
controller state, events and loop diagnostics are hilrig's own ``hilrig_msgs`` messages, whose
``.msg`` files ship in ``hilrig/recording/msgdefs``. A :class:`ChannelSpec` fixes what does not
change during a session - frame id, joint or axis names, which arrays are filled - so that every
message of a channel has the same layout.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass

from hilrig.errors import RecordingError

PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"


class MessageType(enum.Enum):
    """The ROS 2 message types of a session; the value is the MCAP schema name."""

    WRENCH = "geometry_msgs/msg/WrenchStamped"
    JOINT_STATE = "sensor_msgs/msg/JointState"
    POSE = "geometry_msgs/msg/PoseStamped"
    CONTROLLER_STATE = "hilrig_msgs/msg/ControllerState"
    EVENT = "hilrig_msgs/msg/Event"
    LOOP_DIAGNOSTICS = "hilrig_msgs/msg/LoopDiagnostics"
    STRING = "std_msgs/msg/String"


#: The topics of docs/recording-format.md and their types (plus the URDF, as ROS publishes it).
TOPICS: Mapping[str, MessageType] = {
    "/robot_description": MessageType.STRING,
    "/ft/wrist": MessageType.WRENCH,
    "/ft/base": MessageType.WRENCH,
    "/joint_states": MessageType.JOINT_STATE,
    "/controller/input": MessageType.WRENCH,
    "/controller/state": MessageType.CONTROLLER_STATE,
    "/trajectory/desired": MessageType.POSE,
    "/trajectory/commanded": MessageType.JOINT_STATE,
    "/robot/servo": MessageType.JOINT_STATE,
    "/events": MessageType.EVENT,
    "/diagnostics/loop": MessageType.LOOP_DIAGNOSTICS,
}

JOINT_ARRAYS = ("position", "velocity", "effort")
JOINT_NAMES = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
AXIS_NAMES = ("x", "y", "z", *JOINT_NAMES)
AXES = len(AXIS_NAMES)  # the controller's axes: x, y, z (base frame), then the joints


@dataclass(frozen=True)
class TickField:
    """One field of the loop's tick row: numpy scalar ``kind``, ``size`` values (0: a scalar),
    ``unit`` ("x,y,z|joints" where the Cartesian axes and the joints differ), and ``state``:
    the ``hilrig_msgs/msg/ControllerState`` array it fills ("" for none)."""

    name: str
    kind: str
    size: int
    unit: str
    state: str = ""


#: The tick row, the one definition: the rig builds its ring dtype from it and the recorder
#: reads the fields by name. Per-axis fields have ``AXES`` values, in ``AXIS_NAMES`` order.
TICK_FIELDS = (
    TickField("t_ns", "int64", 0, "ns"),  # the tick's start (after its deadline), host monotonic
    TickField("tick", "int64", 0, "1"),
    TickField("force", "float64", AXES, "N|N*m", state="force"),  # compensated controller input
    TickField("moment", "float64", 3, "N*m"),  # compensated wrist moment, base frame
    TickField("offset", "float64", AXES, "m|rad", state="offset"),  # e
    TickField("offset_rate", "float64", AXES, "m/s|rad/s", state="offset_rate"),  # e'
    TickField("damping", "float64", AXES, "N*s/m|N*m*s/rad", state="damping"),
    TickField("stiffness", "float64", AXES, "N/m|N*m/rad", state="stiffness"),
    TickField("chi", "float64", AXES, "1", state="chi"),
    TickField("zeta", "float64", AXES, "1", state="zeta"),
    TickField("contact", "int8", AXES, "ContactState", state="contact_state"),
    TickField("desired_position", "float64", 3, "m"),  # X_d, base frame
    TickField("desired_orientation", "float64", 4, "1"),  # X_d, quaternion x y z w
    TickField("commanded_q", "float64", len(JOINT_NAMES), "rad"),  # the joint targets sent
    TickField("period_ns", "int64", 0, "ns"),  # since the previous tick's start
    TickField("compute_ns", "int64", 0, "ns"),  # work of this tick
    TickField("lateness_ns", "int64", 0, "ns"),  # start - deadline
    TickField("overruns", "int64", 0, "1"),  # ticks so far whose work ran past the next deadline
    TickField("queue_drops", "int64", 0, "1"),  # rows the recorder rings refused so far
)
#: The ControllerState arrays, one value per axis, in the tick row's (and the message's) order.
CONTROLLER_ARRAYS = tuple(f.state for f in TICK_FIELDS if f.state)

#: rosbag2's QoS of a publisher with the ROS 2 default profile (reliable, volatile, keep last
#: 10), written with numeric policies: every rosbag2 since Foxy reads these (see the
#: ``rosbag2`` metadata record the writer adds, and docs/recording-format.md).
OFFERED_QOS_PROFILES = """\
- history: 1
  depth: {depth}
  reliability: 1
  durability: {durability}
  deadline:
    sec: 0
    nsec: 0
  lifespan:
    sec: 0
    nsec: 0
  liveliness: 1
  liveliness_lease_duration:
    sec: 0
    nsec: 0
  avoid_ros_namespace_conventions: false
"""


@dataclass(frozen=True)
class ChannelSpec:
    """One channel of a session and the shape its messages keep for the whole recording.

    ``names``: joint names (JointState) or axis names (ControllerState), e.g. ``("x", "y",
    "z")`` or ``("joint1", ..., "joint6")``. ``arrays``: which JointState arrays are filled (the
    commanded joint targets fill only ``position``). ``controller``: the control law's name.
    ``device_clock``: the device stamps its samples, whose ``device_t_ns`` and ``device_seq``
    become the MCAP publish time and sequence (otherwise: the log time and a counter).
    ``latched``: offered as transient local, like ``/robot_description``, so that a replay
    hands the last message to late subscribers.
    """

    topic: str
    type: MessageType
    frame_id: str = ""
    names: tuple[str, ...] = ()
    arrays: tuple[str, ...] = JOINT_ARRAYS
    controller: str = ""
    device_clock: bool = False
    latched: bool = False

    def __post_init__(self) -> None:
        if not self.topic.startswith("/"):
            raise RecordingError(f"topic {self.topic!r} must start with '/'")
        needs_names = self.type in (MessageType.JOINT_STATE, MessageType.CONTROLLER_STATE)
        if needs_names and not self.names:
            raise RecordingError(f"channel {self.topic}: {self.type.value} needs names")
        if not set(self.arrays) <= set(JOINT_ARRAYS) or "position" not in self.arrays:
            raise RecordingError(f"channel {self.topic}: arrays must include position")

    @property
    def shape(self) -> dict[str, object]:
        """Strings and sequence lengths of every message (see :func:`.cdr.prototype`)."""
        shape: dict[str, object] = {"header.frame_id": self.frame_id}
        n = len(self.names)
        if self.type is MessageType.JOINT_STATE:
            shape["name"] = list(self.names)
            shape.update({a: n if a in self.arrays else 0 for a in JOINT_ARRAYS})
        elif self.type is MessageType.CONTROLLER_STATE:
            shape["controller"] = self.controller
            shape["axis_names"] = list(self.names)
            shape.update(dict.fromkeys(CONTROLLER_ARRAYS, n))
        return shape

    @property
    def metadata(self) -> dict[str, str]:
        """Channel metadata: rosbag2's ``offered_qos_profiles`` and where the clocks went."""
        qos = OFFERED_QOS_PROFILES.format(
            depth=1 if self.latched else 10, durability=1 if self.latched else 2
        )
        return {
            "offered_qos_profiles": qos,
            "hilrig.publish_time": "device_time" if self.device_clock else "log_time",
            "hilrig.sequence": "device_sequence" if self.device_clock else "channel_counter",
        }


def default_channels(
    *,
    joint_names: tuple[str, ...] = JOINT_NAMES,
    axis_names: tuple[str, ...] = AXIS_NAMES,
    controller: str = "adaptive",
    base_frame: str = "base_link",
) -> list[ChannelSpec]:
    """The channels of docs/recording-format.md: an AUBO-i5, both F/T sensors, one controller."""
    wrench = MessageType.WRENCH
    return [
        ChannelSpec("/ft/wrist", wrench, frame_id="ft_wrist"),
        ChannelSpec("/ft/base", wrench, frame_id="ft_base"),
        ChannelSpec("/joint_states", MessageType.JOINT_STATE, names=joint_names, device_clock=True),
        ChannelSpec("/controller/input", wrench, frame_id=base_frame),
        ChannelSpec(
            "/controller/state",
            MessageType.CONTROLLER_STATE,
            frame_id=base_frame,
            names=axis_names,
            controller=controller,
        ),
        ChannelSpec("/trajectory/desired", MessageType.POSE, frame_id=base_frame),
        ChannelSpec(
            "/trajectory/commanded",
            MessageType.JOINT_STATE,
            names=joint_names,
            arrays=("position",),
        ),
        ChannelSpec(
            "/robot/servo", MessageType.JOINT_STATE, names=joint_names, arrays=("position",)
        ),
        ChannelSpec("/events", MessageType.EVENT),
        ChannelSpec("/diagnostics/loop", MessageType.LOOP_DIAGNOSTICS),
    ]
