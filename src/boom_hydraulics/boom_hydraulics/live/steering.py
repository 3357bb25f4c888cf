"""What a Foxglove client may publish to steer a live run, and how it is read.

A client advertises a channel (topic, encoding ``json`` or ``cdr``, schema name) and sends
messages on it. Two kinds of topic steer the run:

- the valve, on ``/valve_command`` or ``/commands`` (the node's topics): a
  ``boom_hydraulics_msgs/msg/ValveCommand`` (``opening``, with the node's stamp rule), a
  ``std_msgs/msg/Float64MultiArray`` of one value, a ``std_msgs/msg/Float64``, or a
  ``geometry_msgs/msg/Twist`` (Foxglove's Teleop panel: ``linear.x`` is the opening);
- a target angle for the position controller, on ``/boom_sim/target_angle_deg``: a
  ``std_msgs/msg/Float64`` in degrees (the boom moves there at control_max_speed_rad_s, as a
  MoveBoom goal does).

Anything else is refused with one line naming what is taken. JSON messages are the
message's fields as an object (Foxglove's Publish panel writes them so); CDR ones are
decoded with the ROS 2 types (rosbags' typestore), no rclpy.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..bags.encoding import VALVE_COMMAND, message, stamp, to_cdr, typestore

ARRAY = "std_msgs/msg/Float64MultiArray"
FLOAT = "std_msgs/msg/Float64"
TWIST = "geometry_msgs/msg/Twist"
#: The valve topics and the type the node records each as.
VALVE_TOPICS = {"/valve_command": VALVE_COMMAND, "/commands": ARRAY}
TARGET_TOPIC = "/boom_sim/target_angle_deg"
_VALVE_SCHEMAS = (VALVE_COMMAND, ARRAY, FLOAT, TWIST)
ENCODINGS = ("json", "cdr")


class SteeringError(ValueError):
    """A client channel or message this run does not take; the text is one line for the client."""


@dataclass(frozen=True)
class Steer:
    """One advertised client channel that steers the run."""

    topic: str
    encoding: str
    schema: str

    def read(self, data: bytes) -> tuple[float, int]:
        """(the value: an opening, or a target angle in degrees; the command's header stamp in
        ns, 0 when unset) of one message. Raises SteeringError for one that cannot be read."""
        try:
            fields = _fields(json.loads(data)) if self.encoding == "json" else _cdr_fields(data, self.schema)
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            raise SteeringError(
                f"{self.topic}: cannot read a {self.encoding} {self.schema} message ({exc}); {_TAKEN}"
            ) from None
        return _value(self.schema, fields), _stamp_ns(fields)

    def recorded(self, value: float, stamp_ns: int, data: bytes) -> bytes:
        """The CDR bytes the node records for this valve command: as received when it came as
        the node's own type, else that type built from the value (and stamp)."""
        kind = VALVE_TOPICS[self.topic]
        if self.encoding == "cdr" and self.schema == kind:
            return data
        if kind == ARRAY:
            return to_cdr(message(ARRAY, data=_floats([value])))
        return to_cdr(message(VALVE_COMMAND, header={"stamp": stamp(stamp_ns)}, opening=value))

    @property
    def steers_valve(self) -> bool:
        return self.topic in VALVE_TOPICS


_TAKEN = (
    f"publish the valve opening on /valve_command ({VALVE_COMMAND} {{opening: U}}, or {TWIST} linear.x) or "
    f"/commands ({ARRAY} {{data: [U]}}), or a target angle in degrees on {TARGET_TOPIC} ({FLOAT} {{data: DEG}})"
)


def steer_of(topic: str, encoding: str, schema: str) -> Steer:
    """The steering channel a client advertised; SteeringError (one line) for one not taken."""
    if encoding not in ENCODINGS:
        raise SteeringError(f"{topic}: encoding {encoding!r} is not taken (use json or cdr); {_TAKEN}")
    if (topic in VALVE_TOPICS and schema in _VALVE_SCHEMAS) or (topic == TARGET_TOPIC and schema == FLOAT):
        return Steer(topic, encoding, schema)
    raise SteeringError(f"{topic} ({schema or 'no schema'}) steers nothing here; {_TAKEN}")


def _floats(values: list[float]) -> np.ndarray:
    return np.array(values, dtype=np.float64)


def _fields(value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TypeError(f"expected an object of the message's fields, got {value!r}")
    return value


def _cdr_fields(data: bytes, schema: str) -> dict[str, Any]:
    """The fields of a CDR message of ``schema``, as JSON would give them."""
    msg = typestore().deserialize_cdr(data, schema)
    if schema == VALVE_COMMAND:
        return {
            "opening": msg.opening,
            "header": {"stamp": {"sec": msg.header.stamp.sec, "nanosec": msg.header.stamp.nanosec}},
        }
    if schema == TWIST:
        return {"linear": {"x": msg.linear.x}}
    return {"data": msg.data.tolist() if schema == ARRAY else msg.data}


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{what} must be a number, got {value!r}")
    return float(value)


def _value(schema: str, fields: dict[str, Any]) -> float:
    """The opening (or angle) a message's fields carry."""
    if schema == VALVE_COMMAND:
        return _number(fields["opening"], "opening")
    if schema == TWIST:
        return _number(fields["linear"]["x"], "linear.x")
    if schema == ARRAY:
        data = fields["data"]
        if not isinstance(data, list) or len(data) != 1:
            raise ValueError(f"data must hold one value (the valve opening), got {data!r}")
        return _number(data[0], "data[0]")
    return _number(fields["data"], "data")


def _stamp_ns(fields: dict[str, Any]) -> int:
    """A ValveCommand's header stamp in ns (0: unset, or a message without one)."""
    header = fields.get("header")
    if not isinstance(header, dict) or not isinstance(header.get("stamp"), dict):
        return 0
    t = header["stamp"]
    return int(_number(t.get("sec", 0), "header.stamp.sec")) * 1_000_000_000 + int(
        _number(t.get("nanosec", 0), "header.stamp.nanosec")
    )
