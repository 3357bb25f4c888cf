"""The crane's frames, as robot_state_publisher sends them from the URDF and joint_states.

The node leaves TF to robot_state_publisher (its launch file starts one); a live run has no
ROS graph, so it sends what that node would: each fixed joint of the URDF once on
``/tf_static`` (latched), and each moving joint (revolute about its axis, prismatic along
it, by the joint's value) on ``/tf`` with every state. The joints come from the URDF the
run publishes on robot_description, read here, so the frames always follow that text.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..bags.encoding import message, stamp, to_cdr
from .channels import TF_MESSAGE

Vector = tuple[float, float, float]
Rotation = tuple[float, float, float, float]  # x, y, z, w


@dataclass(frozen=True)
class Joint:
    """One URDF joint: its frames, kind, origin (m; roll, pitch, yaw in rad) and axis."""

    name: str
    kind: str  # fixed, revolute, continuous or prismatic
    parent: str
    child: str
    xyz: Vector
    rpy: Vector
    axis: Vector


def _triple(text: str | None, default: Vector) -> Vector:
    if not text:
        return default
    x, y, z = (float(v) for v in text.split())
    return x, y, z


def joints(urdf_text: str) -> list[Joint]:
    """The joints of a URDF, in document order: the robot's own ``<joint>`` elements, not those
    named inside other tags (a ``<ros2_control>`` tag's joints, say)."""
    found = []
    for element in ElementTree.fromstring(urdf_text).findall("joint"):
        origin = element.find("origin")
        axis = element.find("axis")
        found.append(
            Joint(
                element.attrib["name"],
                element.attrib["type"],
                element.find("parent").attrib["link"],  # type: ignore[union-attr]
                element.find("child").attrib["link"],  # type: ignore[union-attr]
                _triple(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0)),
                _triple(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0)),
                _triple(axis.get("xyz") if axis is not None else None, (1.0, 0.0, 0.0)),
            )
        )
    return found


def _product(a: Rotation, b: Rotation) -> Rotation:
    """The Hamilton product a * b (apply b, then a)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def _about(axis: Vector, angle_rad: float) -> Rotation:
    """The rotation by ``angle_rad`` about unit-length ``axis``."""
    s = math.sin(angle_rad / 2)
    norm = math.sqrt(sum(c * c for c in axis)) or 1.0
    return axis[0] / norm * s, axis[1] / norm * s, axis[2] / norm * s, math.cos(angle_rad / 2)


def _rotate(q: Rotation, v: Vector) -> Vector:
    x, y, z, _ = _product(_product(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return x, y, z


def transform(joint: Joint, value: float = 0.0) -> tuple[Vector, Rotation]:
    """The child frame in the parent frame at joint value ``value`` (rad or m): the origin,
    turned by roll, pitch, yaw (URDF: fixed axes x, y, z), then the joint's own motion."""
    roll, pitch, yaw = joint.rpy
    origin = _product(_about((0, 0, 1), yaw), _product(_about((0, 1, 0), pitch), _about((1, 0, 0), roll)))
    if joint.kind in ("revolute", "continuous"):
        return joint.xyz, _product(origin, _about(joint.axis, value))
    if joint.kind == "prismatic":
        shift = _rotate(origin, tuple(c * value for c in joint.axis))  # type: ignore[arg-type]
        return (joint.xyz[0] + shift[0], joint.xyz[1] + shift[1], joint.xyz[2] + shift[2]), origin
    return joint.xyz, origin


def _stamped(joint: Joint, stamp_ns: int, value: float = 0.0) -> object:
    (x, y, z), (qx, qy, qz, qw) = transform(joint, value)
    return message(
        "geometry_msgs/msg/TransformStamped",
        header={"stamp": stamp(stamp_ns), "frame_id": joint.parent},
        child_frame_id=joint.child,
        transform={"translation": {"x": x, "y": y, "z": z}, "rotation": {"x": qx, "y": qy, "z": qz, "w": qw}},
    )


def static_frames(urdf_joints: Sequence[Joint], stamp_ns: int) -> bytes:
    """The TFMessage (CDR) of the fixed joints, for /tf_static."""
    return to_cdr(message(TF_MESSAGE, transforms=[_stamped(j, stamp_ns) for j in urdf_joints if j.kind == "fixed"]))


def moving_frames(urdf_joints: Sequence[Joint], values: Mapping[str, float], stamp_ns: int) -> bytes:
    """The TFMessage (CDR) of the moving joints at joint ``values`` (name -> rad or m), for /tf."""
    moving = [_stamped(j, stamp_ns, values[j.name]) for j in urdf_joints if j.kind != "fixed" and j.name in values]
    return to_cdr(message(TF_MESSAGE, transforms=moving))
