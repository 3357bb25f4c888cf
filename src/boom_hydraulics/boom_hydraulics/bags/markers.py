"""The crane as RViz/Foxglove markers in base_link, as CDR bytes: no TF needed to see it move.

One MarkerArray per instant: the column, the boom, the payload, the cylinder barrel
coloured by the piston-chamber pressure, the rod coloured by the rod-chamber pressure,
and a text over the cylinder. Pressure colours run from blue (tank) over green to yellow
(supply pressure); a chamber that cavitates or reaches its relief valve turns red, and the
text names it.

:class:`CraneMarkers` works out what depends only on the parameters once and gives each
instant's markers as fields (:class:`.cdr.MarkerFields`), packed straight into CDR
(:func:`.cdr.marker_array`), with no rclpy and no message object: the node publishes and
records these bytes, and so does ``boom-sim live`` (both through :class:`.messages.TickMessages`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..model.kinematics import Chain, along_boom_xz, base_xz, chain, pivot_xz
from ..model.robot_description import BASE_FRAME, drawing
from . import cdr
from .cdr import MarkerFields

MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
CYLINDER, SPHERE, TEXT_VIEW_FACING = 3, 2, 9  # visualization_msgs/Marker's types
NAMESPACE = "boom_crane"
Colour = tuple[float, float, float, float]  # r g b a, 0..1
RED: Colour = (1.0, 0.0, 0.0, 1.0)
WHITE: Colour = (1.0, 1.0, 1.0, 1.0)
COLUMN_GREY: Colour = (0.55, 0.57, 0.6, 1.0)
BOOM_YELLOW: Colour = (0.95, 0.7, 0.1, 1.0)
PAYLOAD_GREY: Colour = (0.4, 0.4, 0.45, 1.0)
COLUMN_DIAMETER_M = 0.15
TEXT_HEIGHT_M = 0.08
TEXT_ABOVE_M = 0.25  # the text's height over the cylinder's middle
_UPRIGHT = (0.0, 0.0, 0.0, 1.0)
_ID = {"column": 0, "boom": 1, "payload": 2, "barrel": 3, "rod": 4, "text": 5}


def pressure_colour(pressure_pa: float, p: Any) -> Colour:
    """Blue at tank pressure, green half-way, yellow at supply pressure."""
    low, high = p.tank_pressure_pa, p.supply_pressure_pa
    f = min(1.0, max(0.0, (pressure_pa - low) / (high - low))) if high > low else 0.0
    return (f, min(1.0, 0.5 + f), max(0.0, 1.0 - 2.0 * f), 1.0)


def chamber_alarm(out: Mapping[str, Any], chamber: int, p: Any) -> str:
    """'cavitation', 'relief' or '' for chamber 1 (piston) or 2 (rod)."""
    if float(out.get(f"void{chamber}", 0.0)) > 0.0:
        return "cavitation"
    if float(out[f"p{chamber}"]) >= p.relief_pressure_pa:
        return "relief"
    return ""


def _segment(
    marker_id: str, start: tuple[float, float], end: tuple[float, float], diameter_m: float, colour: Colour
) -> MarkerFields:
    """A cylinder marker from ``start`` to ``end`` (x, z in base_link, m)."""
    dx, dz = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dz)
    theta = math.atan2(dx, dz)  # a marker cylinder lies along z; turn it about y onto the segment
    return MarkerFields(
        _ID[marker_id],
        CYLINDER,
        (start[0] + dx / 2, 0.0, start[1] + dz / 2),
        (0.0, math.sin(theta / 2), 0.0, math.cos(theta / 2)),
        (diameter_m, diameter_m, max(length, 1e-6)),
        colour,
    )


class CraneMarkers:
    """The markers of the crane of Parameters ``params``; what depends on them alone (the
    drawn sizes, the pivot, the cylinder base, the column) is worked out here, once."""

    def __init__(self, params: Any) -> None:
        self.params = params
        self._drawing = drawing(params)
        self._pivot = pivot_xz(params)
        self._base = base_xz(params)
        self._column = _segment("column", (0.0, 0.0), self._pivot, COLUMN_DIAMETER_M, COLUMN_GREY)

    def fields(self, out: Mapping[str, Any], c: Chain) -> list[MarkerFields]:
        """The markers of the outputs ``out`` of one instant, whose joint values are ``c``
        (:func:`..model.kinematics.chain` of its rod length), in the order they are published."""
        p, d, o, a = self.params, self._drawing, self._pivot, self._base
        tip = along_boom_xz(p, c.boom_rad, p.boom_length_m)
        bent = float(out.get("boom_deflection", 0.0))  # the elastic boom's tip, normal to the boom
        tip = (tip[0] - bent * math.sin(c.boom_rad), tip[1] + bent * math.cos(c.boom_rad))
        ux, uz = math.cos(c.barrel_rad), math.sin(c.barrel_rad)
        rod_start = c.rod_m - d.rod_length
        eye = (a[0] + c.rod_m * ux, a[1] + c.rod_m * uz)
        alarms = [chamber_alarm(out, 1, p), chamber_alarm(out, 2, p)]
        p1, p2 = float(out["p1"]), float(out["p2"])
        barrel_end = (a[0] + d.barrel_length * ux, a[1] + d.barrel_length * uz)
        barrel_colour = RED if alarms[0] else pressure_colour(p1, p)
        rod_colour = RED if alarms[1] else pressure_colour(p2, p)
        radius = d.payload_radius
        flags = [f"{name} {alarm}" for name, alarm in zip(("piston", "rod"), alarms) if alarm]
        text = f"p1 {p1 / 1e6:.1f} MPa  p2 {p2 / 1e6:.1f} MPa" + ("  " + ", ".join(flags).upper() if flags else "")
        return [
            self._column,
            _segment("boom", o, tip, d.boom_width, BOOM_YELLOW),
            MarkerFields(
                _ID["payload"],
                SPHERE,
                (tip[0], 0.0, tip[1] - radius),
                _UPRIGHT,
                (2 * radius, 2 * radius, 2 * radius),
                PAYLOAD_GREY,
            ),
            _segment("barrel", a, barrel_end, 2 * d.barrel_radius, barrel_colour),
            _segment("rod", (a[0] + rod_start * ux, a[1] + rod_start * uz), eye, p.rod_diameter_m, rod_colour),
            MarkerFields(
                _ID["text"],
                TEXT_VIEW_FACING,
                ((a[0] + eye[0]) / 2, 0.0, (a[1] + eye[1]) / 2 + TEXT_ABOVE_M),
                _UPRIGHT,
                (0.0, 0.0, TEXT_HEIGHT_M),
                RED if flags else WHITE,
                text,
            ),
        ]

    def cdr(self, out: Mapping[str, Any], c: Chain, stamp_ns: int) -> bytes:
        """The MarkerArray of :meth:`fields`, stamped ``stamp_ns``, as CDR bytes."""
        return cdr.marker_array(stamp_ns, BASE_FRAME, NAMESPACE, self.fields(out, c))


def crane_markers(out: Mapping[str, Any], stamp_ns: int, p: Any) -> bytes:
    """The visualization_msgs/MarkerArray (CDR) of the outputs ``out`` of one instant, stamped
    ``stamp_ns`` (Parameters ``p`` for the dimensions)."""
    return CraneMarkers(p).cdr(out, chain(p, float(out["q1"]), 0.0), stamp_ns)
