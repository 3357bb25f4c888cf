"""The crane as a URDF, built from a parameter set (a, b, h, L1, stroke, masses, diameters).

The closed chain is cut open into a tree (see :mod:`kinematics`):

    base_link (column foot)
    ├── boom_joint (revolute at O, axis -y)          -> boom ── boom_tip -> payload
    │     (boom_tip_joint: fixed; prismatic along the boom's z with the elastic boom on, its
    │      value the tip's deflection, docs/model.md "Elastic boom")
    │                                                        └─ boom_rod_mount (K, fixed)
    └── cylinder_barrel_joint (revolute at A, axis -y) -> cylinder_barrel
        └── cylinder_joint (prismatic along x, q1)       -> cylinder_rod ── rod_eye (fixed)

With the joint values the node publishes, ``rod_eye`` lands on ``boom_rod_mount``.
``boom-sim urdf`` writes it; the node publishes it on robot_description; the package ships
``urdf/boom_crane.urdf`` for config/default.yaml (a test keeps the two equal).

A ``<ros2_control>`` tag makes the node the hardware behind ros2_control: ros-controls'
JointState topic hardware interface (:data:`HARDWARE_PLUGIN`) publishes ``boom_joint``'s
position and velocity commands on the node's ``joint_commands`` and reads its state from
the node's ``joint_states``; the topic names are those the node resolves (its namespace and
remappings), by default :data:`JOINT_COMMANDS_TOPIC` and :data:`JOINT_STATES_TOPIC`.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from .geometry import boom_angle_rad, stroke_angles_rad
from .kinematics import base_xz, chain, pivot_height_m

ROBOT_NAME = "boom_crane"
BASE_FRAME = "base_link"
JOINTS = ("boom_joint", "cylinder_barrel_joint", "cylinder_joint")
#: The boom tip's joint: prismatic along the boom's z where the elastic boom is on (joint_states
#: then names it after :data:`JOINTS`, its value the tip's deflection, m), else fixed.
TIP_JOINT = "boom_tip_joint"
#: ros2_control's hardware interface for JointState topics (package
#: joint_state_topic_hardware_interface of ros-controls/topic_based_hardware_interfaces).
HARDWARE_PLUGIN = "joint_state_topic_hardware_interface/JointStateTopicSystem"
#: The node's command and state topics as a node in the root namespace resolves them.
JOINT_COMMANDS_TOPIC = "/joint_commands"
JOINT_STATES_TOPIC = "/joint_states"

_STEEL = "0.55 0.57 0.6 1"
_YELLOW = "0.95 0.7 0.1 1"
_CHROME = "0.85 0.85 0.9 1"


class Drawing(NamedTuple):
    """Sizes of the drawn parts (what the URDF's visuals and the node's markers show), m."""

    boom_width: float
    barrel_radius: float
    barrel_length: float  # from A; retracted, the barrel reaches almost to the rod eye
    rod_length: float  # back from the rod eye: the stroke plus what stays inside the barrel
    payload_radius: float


def drawing(p: Any) -> Drawing:
    """The drawn sizes for Parameters ``p`` (a drawing choice, not model parameters)."""
    q_min, q_max = p.cylinder_min_length_m, p.cylinder_max_length_m
    return Drawing(
        boom_width=max(0.06, 0.05 * p.boom_length_m),
        barrel_radius=0.5 * p.piston_diameter_m + 0.008,  # the wall
        barrel_length=q_min - 0.05,
        rod_length=(q_max - q_min) + 0.1,
        payload_radius=0.1 if p.payload_mass_kg <= 0.0 else max(0.05, 0.1 * (p.payload_mass_kg / 100.0) ** (1 / 3)),
    )


def _num(x: float) -> str:
    return f"{x:.6g}"


def _xyz(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> str:
    return f"{_num(x)} {_num(y)} {_num(z)}"


def _visual(shape: str, xyz: str, rpy: str, material: str) -> str:
    return (
        f'    <visual>\n      <origin xyz="{xyz}" rpy="{rpy}"/>\n      <geometry>{shape}</geometry>\n'
        f'      <material name="{material}"/>\n    </visual>\n'
    )


def _link(name: str, body: str = "", mass_kg: float = 0.0, com_xyz: str = "0 0 0") -> str:
    inertial = ""
    if mass_kg > 0.0:
        inertial = (
            f'    <inertial>\n      <origin xyz="{com_xyz}"/>\n      <mass value="{_num(mass_kg)}"/>\n'
            '      <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/>\n    </inertial>\n'
        )
    return f'  <link name="{name}">\n{body}{inertial}  </link>\n'


def elastic(p: Any) -> bool:
    """Whether Parameters ``p`` have the elastic boom on (its tip a moving joint, :data:`TIP_JOINT`)."""
    return p.boom_bending_stiffness_n_m2 > 0.0


def _joint(
    name: str,
    kind: str,
    parent: str,
    child: str,
    xyz: str,
    limits: tuple[float, float] | None = None,
    axis: str | None = None,
) -> str:
    axis = axis or {"revolute": "0 -1 0", "prismatic": "1 0 0"}.get(kind)
    text = f'  <joint name="{name}" type="{kind}">\n    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
    text += f'    <origin xyz="{xyz}" rpy="0 0 0"/>\n'
    if axis:
        text += f'    <axis xyz="{axis}"/>\n'
    if limits:
        text += f'    <limit lower="{_num(limits[0])}" upper="{_num(limits[1])}" effort="1e6" velocity="10"/>\n'
    return text + "  </joint>\n"


def ros2_control(p: Any, commands_topic: str = JOINT_COMMANDS_TOPIC, states_topic: str = JOINT_STATES_TOPIC) -> str:
    """The ``<ros2_control>`` tag of the crane: the JointState topic hardware interface on the
    node's ``commands_topic`` and ``states_topic``, and ``boom_joint`` with position and velocity
    command and state interfaces (its position starts at the angle of ``initial_length_m``).
    The hardware interface publishes every update (threshold -1), so that a velocity command
    is renewed before the node's command_timeout_s ends it."""
    alpha0 = boom_angle_rad(p.initial_length_m, p.a_m, p.b_m, p.support_height_m)
    return (
        f'  <ros2_control name="{ROBOT_NAME}" type="system">\n'
        "    <hardware>\n"
        f"      <plugin>{HARDWARE_PLUGIN}</plugin>\n"
        f'      <param name="joint_commands_topic">{commands_topic}</param>\n'
        f'      <param name="joint_states_topic">{states_topic}</param>\n'
        '      <param name="trigger_joint_command_threshold">-1</param>\n'
        "    </hardware>\n"
        f'    <joint name="{JOINTS[0]}">\n'
        '      <command_interface name="position"/>\n'
        '      <command_interface name="velocity"/>\n'
        '      <state_interface name="position">\n'
        f'        <param name="initial_value">{_num(alpha0)}</param>\n'
        "      </state_interface>\n"
        '      <state_interface name="velocity"/>\n'
        "    </joint>\n"
        "  </ros2_control>\n"
    )


def urdf(p: Any, commands_topic: str = JOINT_COMMANDS_TOPIC, states_topic: str = JOINT_STATES_TOPIC) -> str:
    """The URDF of the crane with the dimensions of Parameters ``p``, with the ros2_control tag
    of a node whose joint commands and states are on ``commands_topic`` and ``states_topic``."""
    q_min, q_max = p.cylinder_min_length_m, p.cylinder_max_length_m
    alpha_min, alpha_max = stroke_angles_rad(p)
    beta_min, beta_max = sorted((chain(p, q_min, 0.0).barrel_rad, chain(p, q_max, 0.0).barrel_rad))
    height = pivot_height_m(p)
    ax, az = base_xz(p)
    boom_width, barrel_radius, barrel_length, rod_length, payload_radius = drawing(p)
    rod_radius = 0.5 * p.rod_diameter_m
    along_x = f"0 {_num(math.pi / 2)} 0"  # a URDF cylinder lies along z; turn it onto x
    parts = [
        f'<?xml version="1.0"?>\n<!-- {ROBOT_NAME}: generated by boom_hydraulics (boom-sim urdf) from its parameters;'
        f" a = {p.a_m} m, b = {p.b_m} m, h = {p.support_height_m} m, L1 = {p.boom_length_m} m,"
        f" stroke [{q_min}, {q_max}] m -->\n",
        f'<robot name="{ROBOT_NAME}">\n',
        f'  <material name="steel"><color rgba="{_STEEL}"/></material>\n',
        f'  <material name="yellow"><color rgba="{_YELLOW}"/></material>\n',
        f'  <material name="chrome"><color rgba="{_CHROME}"/></material>\n',
        _link(
            BASE_FRAME,
            _visual(f'<box size="{_xyz(0.15, 0.15, height)}"/>', _xyz(0, 0, height / 2), "0 0 0", "steel")
            + _visual(f'<box size="{_xyz(ax + 0.1, 0.1, 0.1)}"/>', _xyz(ax / 2, 0, az), "0 0 0", "steel"),
        ),
        _joint("boom_joint", "revolute", BASE_FRAME, "boom", _xyz(0, 0, height), (alpha_min, alpha_max)),
        _link(
            "boom",
            _visual(
                f'<box size="{_xyz(p.boom_length_m, boom_width, boom_width)}"/>',
                _xyz(p.boom_length_m / 2),
                "0 0 0",
                "yellow",
            ),
            p.boom_mass_kg,
            _xyz(p.boom_length_m / 2),
        ),
        _joint(TIP_JOINT, "fixed", "boom", "boom_tip", _xyz(p.boom_length_m))
        if not elastic(p)
        else _joint(
            TIP_JOINT,
            "prismatic",
            "boom",
            "boom_tip",
            _xyz(p.boom_length_m),
            (-0.2 * p.boom_length_m, 0.2 * p.boom_length_m),
            "0 0 1",
        ),
        _link("boom_tip"),
        _joint("payload_joint", "fixed", "boom_tip", "payload", _xyz(0, 0, -payload_radius)),
        _link(
            "payload",
            _visual(f'<sphere radius="{_num(payload_radius)}"/>', "0 0 0", "0 0 0", "steel"),
            p.payload_mass_kg,
        ),
        _joint("boom_rod_mount_joint", "fixed", "boom", "boom_rod_mount", _xyz(p.a_m)),
        _link("boom_rod_mount"),
        _joint(
            "cylinder_barrel_joint", "revolute", BASE_FRAME, "cylinder_barrel", _xyz(ax, 0, az), (beta_min, beta_max)
        ),
        _link(
            "cylinder_barrel",
            _visual(
                f'<cylinder radius="{_num(barrel_radius)}" length="{_num(barrel_length)}"/>',
                _xyz(barrel_length / 2),
                along_x,
                "steel",
            ),
        ),
        _joint("cylinder_joint", "prismatic", "cylinder_barrel", "cylinder_rod", "0 0 0", (q_min, q_max)),
        _link(
            "cylinder_rod",
            _visual(
                f'<cylinder radius="{_num(rod_radius)}" length="{_num(rod_length)}"/>',
                _xyz(-rod_length / 2),
                along_x,
                "chrome",
            ),
        ),
        _joint("rod_eye_joint", "fixed", "cylinder_rod", "rod_eye", "0 0 0"),
        _link("rod_eye"),
        ros2_control(p, commands_topic, states_topic),
        "</robot>\n",
    ]
    return "".join(parts)
