"""The topics a live run publishes: the node's, as Foxglove channels (CDR, ROS 2 schemas).

Each :class:`Outlet` is one topic with its ROS type, the QoS the node offers on it (what the
bag records) and whether it goes into the bag. The node's topics keep their names
(un-namespaced, as the shipped Foxglove layout expects them); ``/tf`` and ``/tf_static``
stand in for the robot_state_publisher the node's launch file starts, and are not recorded,
as the node does not record them. The schemas are the ``.msg`` texts as rosbag2 stores them
(``ros2msg``), so the Foxglove app decodes the channels as it decodes a ROS 2 bridge's.
"""

from __future__ import annotations

from dataclasses import dataclass

import foxglove
from rosbags.interfaces import Qos

from ..bags.encoding import DRIVE_STATE, SETPOINT_PATH, typestore
from ..bags.recording import Topic, message_definition, offered_qos
from ..errors import RecordingError

NODE = "/boom_sim"  # the node's fully qualified name: its ~/ topics and the bag's run description
JOINT_STATE = "sensor_msgs/msg/JointState"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"


@dataclass(frozen=True)
class Outlet:
    """One published topic: name, ROS type, the QoS the node offers, recorded or not."""

    topic: str
    msgtype: str
    latched: bool = False  # transient local: a subscriber that comes later gets the last message
    recorded: bool = True

    @property
    def offer(self) -> Qos:
        """What the node's publisher offers (depth 10, reliable; latched: depth 1, transient local)."""
        return offered_qos(transient_local=True, depth=1) if self.latched else offered_qos()


DRIVE = Outlet("/drive_state", DRIVE_STATE)
JOINTS = Outlet("/joint_states", JOINT_STATE)
PISTON = Outlet("/piston_pressure", FLUID_PRESSURE)
ROD = Outlet("/rod_pressure", FLUID_PRESSURE)
FORCE = Outlet("/rod_force", "geometry_msgs/msg/WrenchStamped")
HINGE = Outlet("/hinge_wrench", "geometry_msgs/msg/WrenchStamped")
MARKERS = Outlet(f"{NODE}/markers", "visualization_msgs/msg/MarkerArray")
SETPOINT = Outlet(f"{NODE}/setpoint", JOINT_STATE)
PATH = Outlet(f"{NODE}/setpoint_path", SETPOINT_PATH)  # each path the controller starts to follow
DESCRIPTION = Outlet("/robot_description", "std_msgs/msg/String", latched=True)
DIAGNOSTICS = Outlet("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")
TF = Outlet("/tf", TF_MESSAGE, recorded=False)
TF_STATIC = Outlet("/tf_static", TF_MESSAGE, latched=True, recorded=False)
OUTLETS = (DRIVE, JOINTS, PISTON, ROD, FORCE, HINGE, MARKERS, SETPOINT, PATH, DESCRIPTION, DIAGNOSTICS, TF, TF_STATIC)


def schema_text(msgtype: str) -> str:
    """The ros2msg definition of ``msgtype``: the installed ``.msg`` texts as rosbag2 stores
    them, or, for a type with none installed (tf2_msgs), the one rosbags' typestore writes."""
    try:
        return message_definition(msgtype)
    except RecordingError:
        return typestore().generate_msgdef(msgtype, ros_version=2)[0]


def bag_topics() -> list[Topic]:
    """The recorded outlets as the bag's topics, with the node's offers."""
    return [Topic(o.topic, o.msgtype, (o.offer,)) for o in OUTLETS if o.recorded]


def open_channels(context: foxglove.Context) -> dict[Outlet, foxglove.Channel]:
    """A Foxglove channel per outlet in ``context``: CDR messages, ros2msg schemas."""
    return {
        o: foxglove.Channel(
            o.topic,
            schema=foxglove.Schema(name=o.msgtype, encoding="ros2msg", data=schema_text(o.msgtype).encode()),
            message_encoding="cdr",
            context=context,
        )
        for o in OUTLETS
    }
