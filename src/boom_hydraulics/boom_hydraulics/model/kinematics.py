"""Where the parts of the crane are: the closed chain O-K-A cut open into a tree.

Frames follow REP 103: x forward (towards the boom tip when it is level), y left, z up. The
boom and the cylinder turn about axes along -y, so a positive angle lifts. The column's foot
(``base_link``) is on the ground under the boom pivot O.

- O, the boom pivot, is COLUMN_FOOT_M + h above the foot.
- A, the cylinder base on the column, is h below O and sqrt(b^2 - h^2) forward of it (the
  angle OA makes with the vertical is alpha2 = arccos(h / b), eq. 3).
- K, the rod eye on the boom, is a from O along the boom, at elevation alpha (eq. 4).
- The cylinder's angle above the horizontal is beta = atan2(K_z - A_z, K_x - A_x); the rod's
  eye sits q1 from A along it, so it meets K.

Joint values: ``boom_joint`` = alpha, ``cylinder_barrel_joint`` = beta, ``cylinder_joint`` = q1.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

from ..jit import jitable
from .geometry import boom_angle_rad, lever_rad_per_m

#: Height of the cylinder base A above the column's foot, m (a drawing choice, not a parameter).
COLUMN_FOOT_M = 0.2


class Chain(NamedTuple):
    """Joint values of one instant, consistent with each other."""

    boom_rad: float  # alpha
    boom_rate_rad_s: float
    barrel_rad: float  # beta
    barrel_rate_rad_s: float
    rod_m: float  # q1
    rod_rate_m_s: float
    lever_rad_per_m: float  # k = d(alpha)/dq1 (eq. 5)


def pivot_height_m(p: Any) -> float:
    """Height of O above the column's foot, m."""
    return COLUMN_FOOT_M + p.support_height_m


def base_xz(p: Any) -> tuple[float, float]:
    """The cylinder base A in base_link (x, z), m."""
    return cylinder_base_xz(p.b_m, p.support_height_m)


@jitable
def cylinder_base_xz(b_m: float, h_m: float) -> tuple[float, float]:
    """The cylinder base A in base_link (x, z), m, for the geometry's b and h (:func:`base_xz`)."""
    return math.sqrt(b_m * b_m - h_m * h_m), COLUMN_FOOT_M


def pivot_xz(p: Any) -> tuple[float, float]:
    """The boom pivot O in base_link (x, z), m."""
    return 0.0, pivot_height_m(p)


def along_boom_xz(p: Any, alpha_rad: float, distance_m: float) -> tuple[float, float]:
    """The point ``distance_m`` from O along the boom at elevation ``alpha_rad``, in base_link."""
    return boom_point_xz(p.support_height_m, alpha_rad, distance_m)


@jitable
def boom_point_xz(h_m: float, alpha_rad: float, distance_m: float) -> tuple[float, float]:
    """:func:`along_boom_xz` for the geometry's h: O is at (0, COLUMN_FOOT_M + h) (:func:`pivot_xz`)."""
    return 0.0 + distance_m * math.cos(alpha_rad), (COLUMN_FOOT_M + h_m) + distance_m * math.sin(alpha_rad)


@jitable
def barrel_and_lever(q1_m: float, v_m_s: float, a_m: float, b_m: float, h_m: float) -> tuple[float, float, float]:
    """The cylinder barrel's angle beta (rad) and rate (rad/s), and the lever k = d(alpha)/dq1
    (rad/m, eq. 5), at cylinder length ``q1_m`` and rod velocity ``v_m_s`` (compiled code calls
    it for the node's joint states)."""
    alpha = boom_angle_rad(q1_m, a_m, b_m, h_m)
    lever = lever_rad_per_m(q1_m, a_m, b_m)
    alpha_rate = lever * v_m_s
    kx, kz = boom_point_xz(h_m, alpha, a_m)  # K
    ax, az = cylinder_base_xz(b_m, h_m)  # A
    rx, rz = kx - ax, kz - az
    beta = math.atan2(rz, rx)
    # d(beta)/dt = (rx rz' - rz rx') / |r|^2 with r' = a alpha' (-sin alpha, cos alpha)
    barrel_rate = a_m * alpha_rate * (rx * math.cos(alpha) + rz * math.sin(alpha)) / (rx * rx + rz * rz)
    return beta, barrel_rate, lever


def chain(p: Any, q1_m: float, v_m_s: float) -> Chain:
    """Joint values and rates at cylinder length ``q1_m`` and rod velocity ``v_m_s``."""
    alpha = boom_angle_rad(q1_m, p.a_m, p.b_m, p.support_height_m)
    beta, barrel_rate, lever = barrel_and_lever(q1_m, v_m_s, p.a_m, p.b_m, p.support_height_m)
    return Chain(alpha, lever * v_m_s, beta, barrel_rate, q1_m, v_m_s, lever)


def rod_length_m(p: Any, alpha_rad: float) -> float:
    """The cylinder length q1 that puts the boom at ``alpha_rad`` (eq. 1-4 inverted), m."""
    theta = alpha_rad + math.pi / 2.0 - math.acos(p.support_height_m / p.b_m)
    return math.sqrt(p.a_m * p.a_m + p.b_m * p.b_m - 2.0 * p.a_m * p.b_m * math.cos(theta))
