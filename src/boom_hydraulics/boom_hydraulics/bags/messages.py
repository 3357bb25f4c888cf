"""The node's messages of one instant, as CDR bytes: one builder per message type.

Every builder takes what a state publishes (``Simulator.published()``: the outputs, the
cylinder barrel's angle and rate and the lever, in the order of ``PUBLISHED_NAMES``) and the
stamp (ns on the node's clock), and packs the message straight into CDR (:mod:`..bags.cdr`)
with packers bound once, with no message object: the node and ``boom-sim live`` publish
and record these bytes. DriveState follows the one field mapping in :mod:`..bags.encoding`;
JointState, FluidPressure and WrenchStamped are the standard views of the same outputs, the
MarkerArray the drawn crane (:mod:`.markers`). :class:`TickMessages` is what the node calls
each tick: every message of one instant, with what depends only on the parameters worked
out once.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Any

from ..model.kinematics import Chain
from ..model.outputs import PUBLISHED_NAMES
from ..model.robot_description import BASE_FRAME, JOINTS, TIP_JOINT, elastic
from . import cdr
from .encoding import DRIVE_STATE_FIELDS, FLAGS
from .markers import CraneMarkers

CHAMBER_FRAMES = {"p1": "piston_chamber", "p2": "rod_chamber"}
ROD_FRAME = "cylinder_rod"  # x along the rod, positive extending
HINGE_FRAME = "boom"  # the URDF's boom link: x along the boom to the tip, z normal to it

#: Where each of what a state publishes is in ``Simulator.published()``.
AT = {name: i for i, name in enumerate(PUBLISHED_NAMES)}
_Q1, _V, _ALPHA, _ALPHA_RATE, _F = (AT[name] for name in ("q1", "v", "alpha", "alpha_rate", "f_hyd"))
_BARREL, _BARREL_RATE, _LEVER, _P1, _P2 = (AT[name] for name in ("barrel", "barrel_rate", "lever", "p1", "p2"))
_FINITE = AT["finite"]
_ETA, _ETA_RATE, _HINGE_X, _HINGE_Z = (
    AT[n] for n in ("boom_deflection", "boom_deflection_rate", "hinge_force_x", "hinge_force_z")
)
# DriveState's float64 fields and its flags, in the message's order (taken in one call each)
_DRIVE_FLOATS = operator.itemgetter(*(AT[name] for name in DRIVE_STATE_FIELDS.values() if name not in FLAGS))
_DRIVE_FLAGS = operator.itemgetter(*(AT[name] for name in FLAGS))
_DRIVE_STATE = cdr.drive_state_packer(BASE_FRAME, len(DRIVE_STATE_FIELDS) - len(FLAGS), len(FLAGS))
_JOINT_STATE = cdr.joint_state_packer(tuple(JOINTS), (3, 3, 3))
_ELASTIC_JOINT_STATE = cdr.joint_state_packer((*JOINTS, TIP_JOINT), (4, 4, 4))  # the elastic boom's tip too
_PISTON, _ROD = (cdr.fluid_pressure_packer(frame) for frame in CHAMBER_FRAMES.values())
_ROD_FORCE = cdr.wrench_stamped_packer(ROD_FRAME)
_HINGE_FORCE = cdr.wrench_stamped_packer(HINGE_FRAME)
_NO_TORQUE = (0.0, 0.0, 0.0)


def finite(values: Sequence[float]) -> bool:
    """Whether the outputs a state publishes (``values``, as :func:`state_messages` takes
    them) are finite: a NaN is never published (the battery's, NaN in paper mode, are not
    among them)."""
    return values[_FINITE] != 0.0


def drive_state(values: Sequence[float], stamp_ns: int) -> bytes:
    """boom_hydraulics_msgs/DriveState in base_link: each field its output (encoding.DRIVE_STATE_FIELDS)."""
    return _DRIVE_STATE(stamp_ns, _DRIVE_FLOATS(values), [flag != 0.0 for flag in _DRIVE_FLAGS(values)])


def joint_state(values: Sequence[float], stamp_ns: int, elastic_boom: bool = False) -> bytes:
    """The three joints of the URDF, consistent with each other (see model.kinematics):
    boom_joint (rad, rad/s, N m), cylinder_barrel_joint (rad, rad/s; a free pivot, effort 0)
    and cylinder_joint (m, m/s, N). The boom's torque is the rod force over the lever
    k = d(alpha)/dq1 (virtual work: T d(alpha) = F dq1). With ``elastic_boom``, boom_tip_joint
    fourth: the tip's deflection normal to the boom (m, m/s; effort 0)."""
    force = values[_F]
    if elastic_boom:
        return _ELASTIC_JOINT_STATE(
            stamp_ns,
            (values[_ALPHA], values[_BARREL], values[_Q1], values[_ETA]),
            (values[_ALPHA_RATE], values[_BARREL_RATE], values[_V], values[_ETA_RATE]),
            (force / values[_LEVER], 0.0, force, 0.0),
        )
    return _JOINT_STATE(
        stamp_ns,
        (values[_ALPHA], values[_BARREL], values[_Q1]),
        (values[_ALPHA_RATE], values[_BARREL_RATE], values[_V]),
        (force / values[_LEVER], 0.0, force),
    )


def state_messages(values: Sequence[float], stamp_ns: int, elastic_boom: bool = False) -> list[bytes]:
    """The state of one instant as the node publishes it at every tick, in the order of its
    topics drive_state, joint_states, piston_pressure, rod_pressure, rod_force and
    hinge_wrench: the chamber pressures (Pa, absolute) as FluidPressure, the hydraulic force
    on the rod (N) as WrenchStamped, force.x along the rod, and the hinge pin's force on the
    boom at its pivot (N, docs/model.md "Elastic boom", eq. E8) as WrenchStamped in the boom's
    frame (x along the boom, z normal to it; a pin carries no torque). With ``elastic_boom``
    joint_states names the boom tip's joint too."""
    return [
        drive_state(values, stamp_ns),
        joint_state(values, stamp_ns, elastic_boom),
        _PISTON(stamp_ns, values[_P1]),
        _ROD(stamp_ns, values[_P2]),
        _ROD_FORCE(stamp_ns, (values[_F], 0.0, 0.0), _NO_TORQUE),
        _HINGE_FORCE(stamp_ns, (values[_HINGE_X], 0.0, values[_HINGE_Z]), _NO_TORQUE),
    ]


def by_name(values: Sequence[float]) -> dict[str, float]:
    """What a state publishes, by name (flags 1.0 or 0.0)."""
    return dict(zip(PUBLISHED_NAMES, values))


def joints(values: Sequence[float]) -> Chain:
    """The joint values of what a state publishes."""
    return Chain(
        values[_ALPHA],
        values[_ALPHA_RATE],
        values[_BARREL],
        values[_BARREL_RATE],
        values[_Q1],
        values[_V],
        values[_LEVER],
    )


class TickMessages:
    """Every message of one instant for Parameters ``params`` (the node makes a new one when
    they change): the state messages, and the markers when asked for."""

    def __init__(self, params: Any) -> None:
        self.params = params
        self.crane = CraneMarkers(params)
        self.elastic_boom = elastic(params)

    def state(self, values: Sequence[float], stamp_ns: int, markers: bool) -> list[bytes]:
        """The messages of :func:`state_messages` of what a state publishes (``values``) and,
        with ``markers``, the MarkerArray after them, as CDR bytes."""
        packed = state_messages(values, stamp_ns, self.elastic_boom)
        if markers:
            packed.append(self.crane.cdr(by_name(values), joints(values), stamp_ns))
        return packed
