"""The crane as RViz/Foxglove markers in base_link, as CDR bytes: no TF needed to see it move.

One MarkerArray per instant: the column, the boom, the payload, the cylinder barrel
coloured by the piston-chamber pressure, the rod coloured by the rod-chamber pressure,
and a text over the cylinder. Pressure colours run from blue (tank) over green to yellow
(supply pressure); a chamber that cavitates or reaches its relief valve turns red, and the
text names it. Built as rosbags messages (:func:`.encoding.message`) and packed to CDR, with
no rclpy: the node publishes and records these bytes, and so does ``boom-sim live``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..model.kinematics import along_boom_xz, base_xz, chain, pivot_xz
from ..model.robot_description import BASE_FRAME, drawing
from .encoding import message, stamp, to_cdr

MARKER = "visualization_msgs/msg/Marker"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
CYLINDER, SPHERE, TEXT_VIEW_FACING, ADD = 3, 2, 9, 0  # Marker.type and Marker.action
NAMESPACE = "boom_crane"
Colour = dict[str, float]  # std_msgs/ColorRGBA's fields
RED: Colour = {"r": 1.0, "g": 0.0, "b": 0.0, "a": 1.0}


def pressure_colour(pressure_pa: float, p: Any) -> Colour:
    """Blue at tank pressure, green half-way, yellow at supply pressure."""
    low, high = p.tank_pressure_pa, p.supply_pressure_pa
    f = min(1.0, max(0.0, (pressure_pa - low) / (high - low))) if high > low else 0.0
    return {"r": f, "g": min(1.0, 0.5 + f), "b": max(0.0, 1.0 - 2.0 * f), "a": 1.0}


def chamber_alarm(out: Mapping[str, Any], chamber: int, p: Any) -> str:
    """'cavitation', 'relief' or '' for chamber 1 (piston) or 2 (rod)."""
    if float(out.get(f"void{chamber}", 0.0)) > 0.0:
        return "cavitation"
    if float(out[f"p{chamber}"]) >= p.relief_pressure_pa:
        return "relief"
    return ""


def _marker(marker_id: str, kind: int, position: tuple[float, float], colour: Colour, **fields: Any) -> dict[str, Any]:
    """The fields of one marker of ``kind`` at ``position`` (x, z in base_link), level unless
    ``fields`` give its pose's orientation."""
    pose = {"position": {"x": position[0], "y": 0.0, "z": position[1]}, "orientation": {"w": 1.0}}
    pose.update(fields.pop("pose", {}))
    return {"ns": NAMESPACE, "id": _ID[marker_id], "type": kind, "action": ADD, "pose": pose, "color": colour, **fields}


def _segment(
    marker_id: str, start: tuple[float, float], end: tuple[float, float], diameter_m: float, colour: Colour
) -> dict[str, Any]:
    """A cylinder marker from ``start`` to ``end`` (x, z in base_link)."""
    dx, dz = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dz)
    theta = math.atan2(dx, dz)  # a marker cylinder lies along z; turn it about y onto the segment
    turned = {"x": 0.0, "y": math.sin(theta / 2), "z": 0.0, "w": math.cos(theta / 2)}
    scale = {"x": diameter_m, "y": diameter_m, "z": max(length, 1e-6)}
    middle = (start[0] + dx / 2, start[1] + dz / 2)
    return _marker(marker_id, CYLINDER, middle, colour, pose={"orientation": turned}, scale=scale)


_ID = {"column": 0, "boom": 1, "payload": 2, "barrel": 3, "rod": 4, "text": 5}


def crane_markers(out: Mapping[str, Any], stamp_ns: int, p: Any) -> bytes:
    """The visualization_msgs/MarkerArray (CDR) of the outputs ``out`` of one instant, stamped
    ``stamp_ns`` (Parameters ``p`` for the dimensions)."""
    c = chain(p, float(out["q1"]), 0.0)
    o, a = pivot_xz(p), base_xz(p)
    tip = along_boom_xz(p, c.boom_rad, p.boom_length_m)
    ux, uz = math.cos(c.barrel_rad), math.sin(c.barrel_rad)
    d = drawing(p)
    barrel_end = d.barrel_length
    rod_start = c.rod_m - d.rod_length
    eye = (a[0] + c.rod_m * ux, a[1] + c.rod_m * uz)
    alarms = [chamber_alarm(out, 1, p), chamber_alarm(out, 2, p)]
    radius = d.payload_radius
    flags = [f"{name} {alarm}" for name, alarm in zip(("piston", "rod"), alarms) if alarm]
    text = f"p1 {float(out['p1']) / 1e6:.1f} MPa  p2 {float(out['p2']) / 1e6:.1f} MPa" + (
        "  " + ", ".join(flags).upper() if flags else ""
    )
    markers = [
        _segment("column", (0.0, 0.0), o, 0.15, {"r": 0.55, "g": 0.57, "b": 0.6, "a": 1.0}),
        _segment("boom", o, tip, d.boom_width, {"r": 0.95, "g": 0.7, "b": 0.1, "a": 1.0}),
        _marker(
            "payload",
            SPHERE,
            (tip[0], tip[1] - radius),
            {"r": 0.4, "g": 0.4, "b": 0.45, "a": 1.0},
            scale={"x": 2 * radius, "y": 2 * radius, "z": 2 * radius},
        ),
        _segment(
            "barrel",
            a,
            (a[0] + barrel_end * ux, a[1] + barrel_end * uz),
            2 * d.barrel_radius,
            RED if alarms[0] else pressure_colour(float(out["p1"]), p),
        ),
        _segment(
            "rod",
            (a[0] + rod_start * ux, a[1] + rod_start * uz),
            eye,
            p.rod_diameter_m,
            RED if alarms[1] else pressure_colour(float(out["p2"]), p),
        ),
        _marker(
            "text",
            TEXT_VIEW_FACING,
            ((a[0] + eye[0]) / 2, (a[1] + eye[1]) / 2 + 0.25),
            RED if flags else {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0},
            scale={"z": 0.08},
            text=text,
        ),
    ]
    header = {"stamp": stamp(stamp_ns), "frame_id": BASE_FRAME}
    return to_cdr(message(MARKER_ARRAY, markers=[message(MARKER, header=header, **m) for m in markers]))
