"""The node's messages from model outputs: one builder per message type, as CDR bytes.

DriveState follows the one field mapping in :mod:`..bags.encoding`; JointState, FluidPressure
and WrenchStamped are the standard views of the same outputs, the MarkerArray the drawn crane
(:mod:`.markers`). Every builder takes the outputs of one instant (``Simulator.outputs()``)
and the stamp (ns on the node's clock) and packs the message straight into CDR
(:mod:`..bags.cdr`) with packers bound once, with no message object: the node publishes and
records these bytes. :class:`TickMessages` is what the node calls each tick: every message
of one instant, with what depends only on the parameters worked out once.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..model.kinematics import Chain, chain
from ..model.robot_description import JOINTS
from . import cdr
from .encoding import drive_state_cdr
from .markers import CraneMarkers

CHAMBER_FRAMES = {"p1": "piston_chamber", "p2": "rod_chamber"}
ROD_FRAME = "cylinder_rod"  # x along the rod, positive extending

#: A boom_hydraulics_msgs/DriveState of the outputs: drive_state(out, stamp_ns, frame_id=BASE_FRAME).
drive_state = drive_state_cdr

_JOINT_STATE = cdr.joint_state_packer(tuple(JOINTS), (3, 3, 3))
_PRESSURES = [(name, cdr.fluid_pressure_packer(frame)) for name, frame in CHAMBER_FRAMES.items()]
_ROD_FORCE = cdr.wrench_stamped_packer(ROD_FRAME)
_NO_TORQUE = (0.0, 0.0, 0.0)


def joint_state(out: Mapping[str, Any], stamp_ns: int, p: Any, c: Chain | None = None) -> bytes:
    """The three joints of the URDF, consistent with each other (see model.kinematics):
    boom_joint (rad, rad/s, N m), cylinder_barrel_joint (rad, rad/s; a free pivot, effort 0)
    and cylinder_joint (m, m/s, N). The boom's torque is the rod force over the lever
    k = d(alpha)/dq1 (virtual work: T d(alpha) = F dq1). ``c``: the chain of this instant,
    where the caller has it."""
    q1, v = float(out["q1"]), float(out["v"])
    if c is None:
        c = chain(p, q1, v)
    force = float(out["f_hyd"])
    return _JOINT_STATE(
        stamp_ns,
        (float(out["alpha"]), c.barrel_rad, q1),
        (float(out["alpha_rate"]), c.barrel_rate_rad_s, v),
        (force / c.lever_rad_per_m, 0.0, force),
    )


def chamber_pressures(out: Mapping[str, Any], stamp_ns: int) -> list[bytes]:
    """Piston- and rod-chamber pressures (Pa, absolute) as FluidPressure, in that order."""
    return [pressure(stamp_ns, float(out[name])) for name, pressure in _PRESSURES]


def rod_force(out: Mapping[str, Any], stamp_ns: int) -> bytes:
    """The hydraulic force on the rod (N) as WrenchStamped, force.x along the rod."""
    return _ROD_FORCE(stamp_ns, (float(out["f_hyd"]), 0.0, 0.0), _NO_TORQUE)


def state_messages(out: Mapping[str, Any], stamp_ns: int, p: Any, c: Chain | None = None) -> list[bytes]:
    """The state of one instant as the node publishes it at every tick, in the order of
    its topics drive_state, joint_states, piston_pressure, rod_pressure and rod_force
    (``c``: the chain of this instant, where the caller has it)."""
    piston, rod = chamber_pressures(out, stamp_ns)
    return [drive_state(out, stamp_ns), joint_state(out, stamp_ns, p, c), piston, rod, rod_force(out, stamp_ns)]


class TickMessages:
    """Every message of one instant for Parameters ``params`` (the node makes a new one when
    they change): the state messages, and the markers when asked for."""

    def __init__(self, params: Any) -> None:
        self.params = params
        self.crane = CraneMarkers(params)

    def state(self, out: Mapping[str, Any], stamp_ns: int, markers: bool) -> list[bytes]:
        """The messages of :func:`state_messages` and, with ``markers``, the MarkerArray
        after them, as CDR bytes."""
        c = chain(self.params, float(out["q1"]), float(out["v"]))
        packed = state_messages(out, stamp_ns, self.params, c)
        if markers:
            packed.append(self.crane.cdr(out, c, stamp_ns))
        return packed
