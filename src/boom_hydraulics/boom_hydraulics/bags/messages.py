"""The node's messages from model outputs: one builder per message type, as CDR bytes.

DriveState follows the one field mapping in :mod:`..bags.encoding`; JointState, FluidPressure
and WrenchStamped are the standard views of the same outputs. Every builder takes the
outputs of one instant (``Simulator.outputs()``) and the stamp (ns on the node's clock) and
packs the message straight into CDR (:mod:`..bags.cdr`), with no message object: the node
publishes and records these bytes.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..model.kinematics import chain
from ..model.robot_description import JOINTS
from . import cdr
from .encoding import drive_state_cdr

CHAMBER_FRAMES = {"p1": "piston_chamber", "p2": "rod_chamber"}
ROD_FRAME = "cylinder_rod"  # x along the rod, positive extending

#: A boom_hydraulics_msgs/DriveState of the outputs: drive_state(out, stamp_ns, frame_id=BASE_FRAME).
drive_state = drive_state_cdr


def joint_state(out: Mapping[str, Any], stamp_ns: int, p: Any) -> bytes:
    """The three joints of the URDF, consistent with each other (see model.kinematics):
    boom_joint (rad, rad/s, N m), cylinder_barrel_joint (rad, rad/s; a free pivot, effort 0)
    and cylinder_joint (m, m/s, N). The boom's torque is the rod force over the lever
    k = d(alpha)/dq1 (virtual work: T d(alpha) = F dq1)."""
    c = chain(p, float(out["q1"]), float(out["v"]))
    force = float(out["f_hyd"])
    return cdr.joint_state(
        stamp_ns,
        JOINTS,
        [float(out["alpha"]), c.barrel_rad, float(out["q1"])],
        [float(out["alpha_rate"]), c.barrel_rate_rad_s, float(out["v"])],
        [force / c.lever_rad_per_m, 0.0, force],
    )


def chamber_pressures(out: Mapping[str, Any], stamp_ns: int) -> list[bytes]:
    """Piston- and rod-chamber pressures (Pa, absolute) as FluidPressure, in that order."""
    return [cdr.fluid_pressure(stamp_ns, frame, float(out[name])) for name, frame in CHAMBER_FRAMES.items()]


def rod_force(out: Mapping[str, Any], stamp_ns: int) -> bytes:
    """The hydraulic force on the rod (N) as WrenchStamped, force.x along the rod."""
    return cdr.wrench_stamped(stamp_ns, ROD_FRAME, (float(out["f_hyd"]), 0.0, 0.0), (0.0, 0.0, 0.0))


def state_messages(out: Mapping[str, Any], stamp_ns: int, p: Any) -> list[bytes]:
    """The state of one instant as the node publishes it at every tick, in the order of
    its topics drive_state, joint_states, piston_pressure, rod_pressure and rod_force."""
    piston, rod = chamber_pressures(out, stamp_ns)
    return [drive_state(out, stamp_ns), joint_state(out, stamp_ns, p), piston, rod, rod_force(out, stamp_ns)]
