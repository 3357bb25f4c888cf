"""Messages as CDR bytes without ROS: what the node and the tools write into bags.

DriveState, the setpoint's JointState and EnergyLedger are packed directly (:mod:`cdr`);
other messages are encoded with rosbags' typestore (Jazzy's types plus this package's
messages, read from their installed .msg). Both write canonical CDR, which every reader
takes (rclpy's serializer leaves trailing padding after empty 8-byte sequences, which
strict readers refuse), and need no rclpy.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype
from rosbags.typesys.store import Typestore

from ..model.robot_description import BASE_FRAME
from ..model.setpoints import CUBIC, LINEAR, QUINTIC, SetpointPath, knot_offsets_ns
from . import cdr
from .recording import interface_file

DRIVE_STATE = "boom_hydraulics_msgs/msg/DriveState"
VALVE_COMMAND = "boom_hydraulics_msgs/msg/ValveCommand"
ENERGY_LEDGER = "boom_hydraulics_msgs/msg/EnergyLedger"
SETPOINT_PATH = "boom_hydraulics_msgs/msg/SetpointPath"

#: DriveState field -> model output name (simulation.OUTPUTS), in the message's order.
DRIVE_STATE_FIELDS: dict[str, str] = {
    "rod_position_m": "q1",
    "rod_velocity_m_s": "v",
    "rod_acceleration_m_s2": "a",
    "boom_angle_rad": "alpha",
    "boom_rate_rad_s": "alpha_rate",
    "piston_pressure_pa": "p1",
    "rod_pressure_pa": "p2",
    "piston_flow_m3_s": "q_in1",
    "rod_flow_m3_s": "q_in2",
    "hydraulic_force_n": "f_hyd",
    "load_force_n": "f_load",
    "valve_command": "u",
    "valve_opening": "x_v",
    "supply_power_w": "power",
    "supply_energy_j": "supply_energy",
    "valve_loss_energy_j": "valve_loss_energy",
    "at_end_stop": "at_end_stop",
    "cavitation": "cavitation",
    "relief_open": "relief_open",
}
FLAGS = ("at_end_stop", "cavitation", "relief_open")
# the outputs of the float64 fields and of the flags, in the message's order (taken in one call each)
_FLOATS = operator.itemgetter(*(name for name in DRIVE_STATE_FIELDS.values() if name not in FLAGS))
_FLAGS = operator.itemgetter(*(name for name in DRIVE_STATE_FIELDS.values() if name in FLAGS))
_PACK_SHAPE = (len(DRIVE_STATE_FIELDS) - len(FLAGS), len(FLAGS))  # float64 fields, flags
_PACK_DRIVE_STATE = cdr.drive_state_packer(BASE_FRAME, *_PACK_SHAPE)


@functools.cache
def typestore() -> Typestore:
    """Jazzy's message types, DriveState, ValveCommand, EnergyLedger and SetpointPath (from the
    workspace's installed .msg)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for msgtype in (DRIVE_STATE, VALVE_COMMAND, ENERGY_LEDGER, SETPOINT_PATH):
        store.register(get_types_from_msg(interface_file(msgtype, ".msg").read_text(), msgtype))
    return store


#: numpy dtypes of the primitive types a message sequence or array holds
_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def _default(kind: tuple[Any, Any]) -> Any:
    """The zero value of one field type of the typestore (rosbags' field definitions)."""
    node, detail = kind
    if node is Nodetype.NAME:
        return message(detail)
    if node is Nodetype.BASE:
        name = detail[0]
        return "" if name == "string" else False if name == "bool" else 0.0 if name.startswith("float") else 0
    element, size = detail  # ARRAY (fixed size) or SEQUENCE (size 0: empty)
    count = size if node is Nodetype.ARRAY else 0
    if element[0] is Nodetype.BASE and element[1][0] != "string":
        return np.zeros(count, dtype=_DTYPES[element[1][0]])
    return [_default(element) for _ in range(count)]


def message(msgtype: str, **fields: Any) -> Any:
    """A message of ``msgtype`` (rosbags' class) with ``fields`` set and every other field at
    its zero value, as a generated message class defaults them; a dict given for a nested
    message sets that message's fields the same way."""
    definitions = typestore().fielddefs[msgtype][1]
    values = {}
    for name, kind in definitions:
        if name not in fields:
            values[name] = _default(kind)
        elif kind[0] is Nodetype.NAME and isinstance(fields[name], dict):
            values[name] = message(kind[1], **fields[name])
        else:
            values[name] = fields[name]
    unknown = set(fields) - set(values)
    if unknown:
        raise TypeError(f"{msgtype} has no field {', '.join(sorted(unknown))}")
    return typestore().types[msgtype](**values)


def to_cdr(msg: Any) -> bytes:
    """The CDR bytes of a message made by :func:`message` (canonical CDR)."""
    return bytes(typestore().serialize_cdr(msg, msg.__msgtype__))


def stamp(stamp_ns: int) -> dict[str, int]:
    """builtin_interfaces/Time of ``stamp_ns`` as the fields :func:`message` takes."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return {"sec": sec, "nanosec": nanosec}


def drive_state_cdr(out: Mapping[str, Any], stamp_ns: int, frame_id: str = BASE_FRAME) -> bytes:
    """CDR of a boom_hydraulics_msgs/DriveState of the model outputs ``out``, stamped ``stamp_ns``."""
    pack = _PACK_DRIVE_STATE if frame_id == BASE_FRAME else cdr.drive_state_packer(frame_id, *_PACK_SHAPE)
    return pack(stamp_ns, _FLOATS(out), _FLAGS(out))


def setpoint_cdr(joint: str, angle_rad: float, rate_rad_s: float, stamp_ns: int) -> bytes:
    """CDR of the sensor_msgs/JointState of a position setpoint (no effort; canonical CDR, with
    no padding after the empty effort, as strict readers such as rosbags require)."""
    return cdr.joint_state(stamp_ns, (joint,), (angle_rad,), (rate_rad_s,), ())


#: Where a recorded setpoint path's first point came from (SetpointPath.start, its constants of
#: the same names): the path's own, the controller's setpoint when the node took the path, or the
#: boom's angle then.
START_OWN, START_SETPOINT, START_BOOM = 0, 1, 2


@dataclass(frozen=True)
class RecordedPath:
    """A setpoint path the node's controller started to follow, as ~/setpoint_path carries it:
    knots ``offsets_ns`` after the instant stamped ``stamp_ns``; ``start`` says where the first
    knot came from (START_OWN, START_SETPOINT or START_BOOM)."""

    stamp_ns: int
    start: int
    offsets_ns: list[int]
    angles_rad: list[float]
    rates_rad_s: list[float]  # zeros for a LINEAR path
    order: int

    @classmethod
    def taken(cls, path: SetpointPath, t0_s: float, stamp_ns: int, start: int) -> RecordedPath:
        """The single-set ``path`` the controller takes at simulated time ``t0_s``, the state of
        that instant stamped ``stamp_ns``: its knots after it in whole ns (as it follows them)."""
        angles, rates = path.angles_rad[:, 0].tolist(), path.rates_rad_s[:, 0].tolist()
        return cls(stamp_ns, start, knot_offsets_ns(path, t0_s), angles, rates, path.order)


def setpoint_path_cdr(joint: str, path: RecordedPath) -> bytes:
    """CDR of the boom_hydraulics_msgs/SetpointPath of a setpoint path: where its first point came
    from, and a trajectory_msgs/JointTrajectory of ``joint``'s positions at each knot (in no frame),
    with velocities for a cubic or quintic path and zero accelerations for a quintic one,
    time_from_start the knot's offset (encoded by rosbags, see :func:`parameter_event_cdr`)."""
    points = [
        message(
            "trajectory_msgs/msg/JointTrajectoryPoint",
            positions=np.array([angle]),
            velocities=np.array([rate] if path.order != LINEAR else [], dtype=float),
            accelerations=np.array([0.0] if path.order == QUINTIC else [], dtype=float),
            time_from_start=stamp(offset_ns),  # (a Duration has a Time's fields)
        )
        for offset_ns, angle, rate in zip(path.offsets_ns, path.angles_rad, path.rates_rad_s)
    ]
    trajectory = {"header": {"stamp": stamp(path.stamp_ns)}, "joint_names": [joint], "points": points}
    return to_cdr(message(SETPOINT_PATH, start=path.start, trajectory=trajectory))


def recorded_path(msg: Any) -> RecordedPath:
    """The setpoint path of a deserialised ~/setpoint_path message (its first joint's values).
    Raises ValueError for a message that is not one."""
    trajectory = msg.trajectory
    if len(trajectory.joint_names) != 1 or not trajectory.points:
        names = list(trajectory.joint_names)
        raise ValueError(f"a setpoint path names one joint and has points; this one names {names}")
    if msg.start not in (START_OWN, START_SETPOINT, START_BOOM):
        raise ValueError(f"a setpoint path starts from its own point, the setpoint or the boom; this one {msg.start}")
    points = trajectory.points
    with_rates = all(len(p.velocities) == 1 for p in points)
    order = (
        QUINTIC if with_rates and all(len(p.accelerations) == 1 for p in points) else CUBIC if with_rates else LINEAR
    )
    return RecordedPath(
        trajectory.header.stamp.sec * 1_000_000_000 + trajectory.header.stamp.nanosec,
        int(msg.start),
        [p.time_from_start.sec * 1_000_000_000 + p.time_from_start.nanosec for p in points],
        [float(p.positions[0]) for p in points],
        [float(p.velocities[0]) if with_rates else 0.0 for p in points],
        order,
    )


_VALUE_FIELDS = {  # rcl_interfaces/msg/ParameterType -> the ParameterValue field holding it
    1: ("bool_value", None),
    2: ("integer_value", None),
    3: ("double_value", None),
    4: ("string_value", None),
    5: ("byte_array_value", np.uint8),
    6: ("bool_array_value", np.bool_),
    7: ("integer_array_value", np.int64),
    8: ("double_array_value", np.float64),
    9: ("string_array_value", list),
}


def parameter_event_cdr(node: str, stamp_ns: int, changed: list[tuple[str, int, Any]]) -> bytes:
    """CDR of an ``rcl_interfaces/msg/ParameterEvent`` announcing ``changed`` (name, ParameterType,
    value) parameters of ``node``. Encoded by rosbags: rclpy's serializer leaves trailing padding
    after the empty 8-byte sequences of ParameterValue, and strict readers refuse that."""
    store = typestore()
    types = store.types
    empty = {
        "bool_value": False,
        "integer_value": 0,
        "double_value": 0.0,
        "string_value": "",
        **{name: [] if kind is list else np.array([], dtype=kind) for name, kind in _VALUE_FIELDS.values() if kind},
    }
    parameters = []
    for name, kind, value in changed:
        field_name, dtype = _VALUE_FIELDS[kind]
        fields = dict(empty)
        fields[field_name] = value if dtype is None else (list(value) if dtype is list else np.array(value, dtype))
        parameter_value = types["rcl_interfaces/msg/ParameterValue"](type=kind, **fields)
        parameters.append(types["rcl_interfaces/msg/Parameter"](name=name, value=parameter_value))
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    event = types["rcl_interfaces/msg/ParameterEvent"](
        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
        node=node,
        new_parameters=[],
        changed_parameters=parameters,
        deleted_parameters=[],
    )
    return bytes(store.serialize_cdr(event, "rcl_interfaces/msg/ParameterEvent"))
