"""Geometry and statics of the boom lifting mechanism (paper eq. 1-6).

Triangle AOK: |OK| = a (rod eye K on the boom), |OA| = b (cylinder base A on the column),
|AK| = q1 (cylinder length, eye to eye). theta = angle AOK = arccos(xi).

Every function works on floats (``xp=math``) and on numpy arrays (``xp=numpy``): only
operators and the functions ``acos``, ``sqrt``, ``cos``, ``sin`` that both namespaces have.

Equations and conventions: docs/model.md, section "Geometry".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable

Num = Any  # float or numpy.ndarray


@jitable
def xi(q1_m: Num, a_m: float, b_m: float) -> Num:
    """xi = cos(theta) = (a^2 + b^2 - q1^2) / (2ab): law of cosines in AOK (eq. 1, under eq. 10)."""
    return (a_m * a_m + b_m * b_m - q1_m * q1_m) / (2.0 * a_m * b_m)


@jitable
def triangle_bounds_m(a_m: float, b_m: float) -> tuple[float, float]:
    """(|b - a|, a + b): the cylinder lengths at which the triangle of eq. 1 degenerates
    (sin(phi) = 0, infinite rod force); the model holds strictly between them, m."""
    return abs(b_m - a_m), a_m + b_m


@jitable
def within_triangle(q1_m: float, a_m: float, b_m: float) -> bool:
    """True where the cylinder length lies strictly inside (|b - a|, a + b) (see
    :func:`triangle_bounds_m`): where the triangle of eq. 1 exists and the model can be evaluated."""
    return abs(b_m - a_m) < q1_m < a_m + b_m


@jitable
def boom_angle_rad(q1_m: Num, a_m: float, b_m: float, h_m: float, xp: ModuleType = math) -> Num:
    """alpha: boom elevation above the horizontal, rad (eq. 4)."""
    return xp.acos(xi(q1_m, a_m, b_m)) - math.pi / 2.0 + xp.acos(h_m / b_m)  # eq. 2-4


@jitable
def cos_boom_angle(q1_m: Num, a_m: float, b_m: float, h_m: float, xp: ModuleType = math) -> Num:
    """cos(alpha) without arccos (eq. 4): alpha = theta - (pi/2 - alpha2), so
    cos(alpha) = cos(theta) sin(alpha2) + sin(theta) cos(alpha2) = xi sqrt(1 - (h/b)^2) + sqrt(1 - xi^2) h/b.
    """
    x = xi(q1_m, a_m, b_m)
    hb = h_m / b_m
    return x * xp.sqrt(1.0 - hb * hb) + xp.sqrt(1.0 - x * x) * hb


@jitable
def sin_boom_angle(q1_m: Num, a_m: float, b_m: float, h_m: float, xp: ModuleType = math) -> Num:
    """sin(alpha) without arccos (eq. 4), as :func:`cos_boom_angle`:
    sin(alpha) = sin(theta) sin(alpha2) - cos(theta) cos(alpha2) = sqrt(1 - xi^2) sqrt(1 - (h/b)^2) - xi h/b.
    """
    x = xi(q1_m, a_m, b_m)
    hb = h_m / b_m
    return xp.sqrt(1.0 - x * x) * xp.sqrt(1.0 - hb * hb) - x * hb


@jitable
def rod_boom_angle_rad(q1_m: Num, a_m: float, b_m: float, xp: ModuleType = math) -> Num:
    """phi: angle between the rod axis and the boom, rad (eq. 5)."""
    return xp.acos((a_m * a_m + q1_m * q1_m - b_m * b_m) / (2.0 * a_m * q1_m))  # eq. 5


@jitable
def lever_rad_per_m(q1_m: Num, a_m: float, b_m: float, xp: ModuleType = math) -> Num:
    """k = d(alpha)/dq1 = q1 / (a b sqrt(1 - xi^2)) = 1 / (a sin(phi)), rad/m.

    The transmission ratio that turns rod force into boom torque (law of sines); it is
    infinite where the triangle degenerates (q1 = |b - a| or a + b).
    """
    x = xi(q1_m, a_m, b_m)
    return q1_m / (a_m * b_m * xp.sqrt(1.0 - x * x))


@jitable
def lever_derivative(q1_m: Num, a_m: float, b_m: float, xp: ModuleType = math) -> Num:
    """dk/dq1 = 1 / (ab s) - q1^2 xi / (a^2 b^2 s^3), s = sqrt(1 - xi^2), rad/m^2."""
    x = xi(q1_m, a_m, b_m)
    s2 = 1.0 - x * x
    s = xp.sqrt(s2)
    ab = a_m * b_m
    return 1.0 / (ab * s) - q1_m * q1_m * x / (ab * ab * s2 * s)


@jitable
def gravity_moment_nm(
    alpha_rad: Num, boom_mass_kg: Num, payload_mass_kg: Num, boom_length_m: float, g_m_s2: float, xp: ModuleType = math
) -> Num:
    """M_g = (m1 L1/2 + mb L1) g cos(alpha): moment of boom and payload weight about O, N m (eq. 6, 9)."""
    return (0.5 * boom_mass_kg + payload_mass_kg) * boom_length_m * g_m_s2 * xp.cos(alpha_rad)


@jitable
def static_rod_force_n(
    q1_m: Num,
    a_m: float,
    b_m: float,
    h_m: float,
    boom_mass_kg: Num,
    payload_mass_kg: Num,
    boom_length_m: float,
    g_m_s2: float,
    xp: ModuleType = math,
) -> Num:
    """F of eq. 6: rod force that holds the boom at rest at q1, N.

    F = (m1 g L1/2 cos(alpha) + mb g L1 cos(alpha)) / (a sin(phi)) = M_g k.
    """
    alpha = boom_angle_rad(q1_m, a_m, b_m, h_m, xp)
    moment = gravity_moment_nm(alpha, boom_mass_kg, payload_mass_kg, boom_length_m, g_m_s2, xp)
    return moment * lever_rad_per_m(q1_m, a_m, b_m, xp)  # eq. 6 with 1/(a sin(phi)) = k


@jitable
def static_rod_force_of(p: Any, q1_m: Num, xp: ModuleType = math) -> Num:
    """:func:`static_rod_force_n` with geometry and masses taken from a Parameters set ``p``, N."""
    return static_rod_force_n(
        q1_m,
        p.a_m,
        p.b_m,
        p.support_height_m,
        p.boom_mass_kg,
        p.payload_mass_kg,
        p.boom_length_m,
        p.gravity_m_s2,
        xp,
    )


def stroke_angles_rad(p: Any) -> tuple[float, float]:
    """Boom angles at the lower and upper end stops of a Parameters set ``p``, rad (eq. 4)."""
    return (
        boom_angle_rad(p.cylinder_min_length_m, p.a_m, p.b_m, p.support_height_m),
        boom_angle_rad(p.cylinder_max_length_m, p.a_m, p.b_m, p.support_height_m),
    )


def outside_stroke(p: Any, angle_rad: float, what: str = "target") -> str | None:
    """Why boom angle ``angle_rad`` cannot be reached within the stroke of ``p``, or None."""
    low, high = stroke_angles_rad(p)
    if low <= angle_rad <= high:
        return None
    return (
        f"{what} {angle_rad:.4f} rad ({math.degrees(angle_rad):.2f} deg) lies outside the stroke's "
        f"[{low:.4f}, {high:.4f}] rad ([{math.degrees(low):.2f}, {math.degrees(high):.2f}] deg)"
    )


@jitable
def piston_area_m2(diameter_m: Num) -> Num:
    """S1 = pi D^2 / 4 (also eq. 17 for the throttle area)."""
    return math.pi * diameter_m * diameter_m / 4.0


@jitable
def annulus_area_m2(piston_diameter_m: Num, rod_diameter_m: Num) -> Num:
    """S2 = pi (D^2 - d^2) / 4: rod-side effective area."""
    return math.pi * (piston_diameter_m * piston_diameter_m - rod_diameter_m * rod_diameter_m) / 4.0


@jitable
def holding_pressure_pa(
    force_n: Num, piston_diameter_m: Num, rod_side_pressure_pa: Num = 0.0, rod_diameter_m: Num = 0.0
) -> Num:
    """Piston-chamber pressure that balances ``force_n`` (Fig. 5): (F + p2 S2) / S1, Pa."""
    s2 = annulus_area_m2(piston_diameter_m, rod_diameter_m)
    return (force_n + rod_side_pressure_pa * s2) / piston_area_m2(piston_diameter_m)
