"""The node's messages from model outputs: one builder per message type.

DriveState follows the one field mapping in :mod:`..bags.encoding`; JointState, FluidPressure
and WrenchStamped are the standard views of the same outputs. Every builder takes the
outputs of one instant (``Simulator.outputs()``) and the stamp to give the message.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import FluidPressure, JointState

from boom_hydraulics_msgs.msg import DriveState

from ..bags.encoding import DRIVE_STATE_FIELDS, FLAGS
from ..model.kinematics import chain
from ..model.robot_description import BASE_FRAME, JOINTS

CHAMBER_FRAMES = {"p1": "piston_chamber", "p2": "rod_chamber"}
ROD_FRAME = "cylinder_rod"  # x along the rod, positive extending


def drive_state(out: Mapping[str, Any], stamp: Any, frame_id: str = BASE_FRAME) -> DriveState:
    """A boom_hydraulics_msgs/DriveState of the outputs ``out``."""
    msg = DriveState()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    for field, name in DRIVE_STATE_FIELDS.items():
        setattr(msg, field, bool(out[name]) if name in FLAGS else float(out[name]))
    return msg


def joint_state(out: Mapping[str, Any], stamp: Any, p: Any) -> JointState:
    """The three joints of the URDF, consistent with each other (see model.kinematics):
    boom_joint (rad, rad/s, N m), cylinder_barrel_joint (rad, rad/s; a free pivot, effort 0)
    and cylinder_joint (m, m/s, N). The boom's torque is the rod force over the lever
    k = d(alpha)/dq1 (virtual work: T d(alpha) = F dq1)."""
    c = chain(p, float(out["q1"]), float(out["v"]))
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(JOINTS)
    msg.position = [float(out["alpha"]), c.barrel_rad, float(out["q1"])]
    msg.velocity = [float(out["alpha_rate"]), c.barrel_rate_rad_s, float(out["v"])]
    msg.effort = [float(out["f_hyd"] / c.lever_rad_per_m), 0.0, float(out["f_hyd"])]
    return msg


def chamber_pressures(out: Mapping[str, Any], stamp: Any) -> list[FluidPressure]:
    """Piston- and rod-chamber pressures (Pa, absolute), in that order."""
    messages = []
    for name, frame in CHAMBER_FRAMES.items():
        msg = FluidPressure(fluid_pressure=float(out[name]), variance=0.0)
        msg.header.stamp, msg.header.frame_id = stamp, frame
        messages.append(msg)
    return messages


def rod_force(out: Mapping[str, Any], stamp: Any) -> WrenchStamped:
    """The hydraulic force on the rod (N), force.x along the rod."""
    msg = WrenchStamped()
    msg.header.stamp, msg.header.frame_id = stamp, ROD_FRAME
    msg.wrench.force.x = float(out["f_hyd"])
    return msg
