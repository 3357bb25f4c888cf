"""The crane as RViz/Foxglove markers in base_link: no TF needed to see it move.

One MarkerArray per instant: the column, the boom, the payload, the cylinder barrel
coloured by the piston-chamber pressure, the rod coloured by the rod-chamber pressure,
and a text over the cylinder. Pressure colours run from blue (tank) over green to yellow
(supply pressure); a chamber that cavitates or reaches its relief valve turns red, and the
text names it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from geometry_msgs.msg import Point, Quaternion
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from ..model.kinematics import along_boom_xz, base_xz, chain, pivot_xz
from ..model.robot_description import BASE_FRAME, drawing

NAMESPACE = "boom_crane"
RED = ColorRGBA(r=1.0, g=0.0, b=0.0, a=1.0)


def pressure_colour(pressure_pa: float, p: Any) -> ColorRGBA:
    """Blue at tank pressure, green half-way, yellow at supply pressure."""
    low, high = p.tank_pressure_pa, p.supply_pressure_pa
    f = min(1.0, max(0.0, (pressure_pa - low) / (high - low))) if high > low else 0.0
    return ColorRGBA(r=f, g=min(1.0, 0.5 + f), b=max(0.0, 1.0 - 2.0 * f), a=1.0)


def chamber_alarm(out: Mapping[str, Any], chamber: int, p: Any) -> str:
    """'cavitation', 'relief' or '' for chamber 1 (piston) or 2 (rod)."""
    if float(out.get(f"void{chamber}", 0.0)) > 0.0:
        return "cavitation"
    if float(out[f"p{chamber}"]) >= p.relief_pressure_pa:
        return "relief"
    return ""


def _segment(marker_id: str, start: tuple[float, float], end: tuple[float, float], diameter_m: float) -> Marker:
    """A cylinder marker from ``start`` to ``end`` (x, z in base_link)."""
    dx, dz = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dz)
    theta = math.atan2(dx, dz)  # a marker cylinder lies along z; turn it about y onto the segment
    m = Marker(ns=NAMESPACE, id=_ID[marker_id], type=Marker.CYLINDER, action=Marker.ADD)
    m.header.frame_id = BASE_FRAME
    m.pose.position.x, m.pose.position.z = start[0] + dx / 2, start[1] + dz / 2
    m.pose.orientation = Quaternion(x=0.0, y=math.sin(theta / 2), z=0.0, w=math.cos(theta / 2))
    m.scale.x = m.scale.y = diameter_m
    m.scale.z = max(length, 1e-6)
    return m


_ID = {"column": 0, "boom": 1, "payload": 2, "barrel": 3, "rod": 4, "text": 5}


def crane_markers(out: Mapping[str, Any], stamp: Any, p: Any) -> MarkerArray:
    """The markers of the outputs ``out`` of one instant (Parameters ``p`` for the dimensions)."""
    c = chain(p, float(out["q1"]), 0.0)
    o, a = pivot_xz(p), base_xz(p)
    tip = along_boom_xz(p, c.boom_rad, p.boom_length_m)
    ux, uz = math.cos(c.barrel_rad), math.sin(c.barrel_rad)
    d = drawing(p)
    barrel_end = d.barrel_length
    rod_start = c.rod_m - d.rod_length
    eye = (a[0] + c.rod_m * ux, a[1] + c.rod_m * uz)
    markers = [
        _segment("column", (0.0, 0.0), o, 0.15),
        _segment("boom", o, tip, d.boom_width),
        _segment("barrel", a, (a[0] + barrel_end * ux, a[1] + barrel_end * uz), 2 * d.barrel_radius),
        _segment("rod", (a[0] + rod_start * ux, a[1] + rod_start * uz), eye, p.rod_diameter_m),
    ]
    column, boom, barrel, rod = markers
    column.color = ColorRGBA(r=0.55, g=0.57, b=0.6, a=1.0)
    boom.color = ColorRGBA(r=0.95, g=0.7, b=0.1, a=1.0)
    alarms = [chamber_alarm(out, 1, p), chamber_alarm(out, 2, p)]
    barrel.color = RED if alarms[0] else pressure_colour(float(out["p1"]), p)
    rod.color = RED if alarms[1] else pressure_colour(float(out["p2"]), p)
    payload = Marker(ns=NAMESPACE, id=_ID["payload"], type=Marker.SPHERE, action=Marker.ADD)
    radius = d.payload_radius
    payload.header.frame_id = BASE_FRAME
    payload.pose.position.x, payload.pose.position.z = tip[0], tip[1] - radius
    payload.pose.orientation.w = 1.0
    payload.scale.x = payload.scale.y = payload.scale.z = 2 * radius
    payload.color = ColorRGBA(r=0.4, g=0.4, b=0.45, a=1.0)
    text = Marker(ns=NAMESPACE, id=_ID["text"], type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
    text.header.frame_id = BASE_FRAME
    text.pose.position = Point(x=(a[0] + eye[0]) / 2, y=0.0, z=(a[1] + eye[1]) / 2 + 0.25)
    text.pose.orientation.w = 1.0
    text.scale.z = 0.08
    flags = [f"{name} {alarm}" for name, alarm in zip(("piston", "rod"), alarms) if alarm]
    text.text = f"p1 {float(out['p1']) / 1e6:.1f} MPa  p2 {float(out['p2']) / 1e6:.1f} MPa" + (
        "  " + ", ".join(flags).upper() if flags else ""
    )
    text.color = RED if flags else ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
    array = MarkerArray()
    for m in (column, boom, payload, barrel, rod, text):
        m.header.stamp = stamp
        array.markers.append(m)
    return array
