"""Dynamics of the boom seen from the cylinder rod (paper eq. 7-11, 16).

With T = J alpha'^2 / 2 (eq. 8) and k = d(alpha)/dq1, the effective mass at the rod is
m(q1) = J k^2, and Lagrange's equation (eq. 7) reads

    m(q1) q1'' + 1/2 m'(q1) q1'^2 = F_rod - M_g k,

with M_g = (m1 L1/2 + mb L1) g cos(alpha) the weight moment. Eq. 16 and the Fig. 7
listing carry an extra factor 1/2 on the whole right-hand side (as if the mass were
2 m(q1)); :func:`paper_acceleration` keeps it, :func:`rod_acceleration` does not.

Equations and conventions: docs/model.md, section "Mechanics".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable
from .geometry import cos_boom_angle, lever_derivative, lever_rad_per_m, xi

Num = Any  # float or numpy.ndarray


@jitable
def boom_inertia_kgm2(boom_mass_kg: Num, payload_mass_kg: Num, boom_length_m: Num) -> Num:
    """J_c1 = m1 L1^2 / 3 + mb L1^2: boom as a rod about its end plus a point payload (eq. 8)."""
    return boom_mass_kg * boom_length_m * boom_length_m / 3.0 + payload_mass_kg * boom_length_m * boom_length_m


@jitable
def effective_mass_kg(inertia_kgm2: Num, lever_rad_per_m: Num) -> Num:
    """m(q1) = J k^2: the boom's inertia seen at the rod (m_np of eq. 11, kg)."""
    return inertia_kgm2 * lever_rad_per_m * lever_rad_per_m


@jitable
def rod_acceleration(
    q1_m: Num,
    v_m_s: Num,
    rod_force_n: Num,
    inertia_kgm2: Num,
    weight_coeff_nm: Num,
    a_m: Num,
    b_m: Num,
    h_m: Num,
    xp: ModuleType = math,
) -> Num:
    """q1'' from the Lagrange equation above (physical mode), m/s^2.

    ``rod_force_n`` is every force on the rod in the extending direction (hydraulic,
    friction, spring, end stops); ``weight_coeff_nm`` = (m1/2 + mb) L1 g, so that
    M_g = weight_coeff cos(alpha).
    q1'' = (F_rod - M_g k) / (J k^2) - (k' / k) q1'^2, since m' / (2 m) = k' / k.
    """
    k = lever_rad_per_m(q1_m, a_m, b_m, xp)
    moment = weight_coeff_nm * cos_boom_angle(q1_m, a_m, b_m, h_m, xp)  # M_g
    return acceleration_at_lever(v_m_s, rod_force_n, inertia_kgm2, moment, k, lever_derivative(q1_m, a_m, b_m, xp))


@jitable
def acceleration_at_lever(
    v_m_s: Num, rod_force_n: Num, inertia_kgm2: Num, moment_nm: Num, lever: Num, lever_slope: Num
) -> Num:
    """:func:`rod_acceleration` from the weight moment M_g, the lever k and dk/dq1 already at hand, m/s^2."""
    return (rod_force_n - moment_nm * lever) / (inertia_kgm2 * lever * lever) - (lever_slope / lever) * v_m_s * v_m_s


@jitable
def load_force_n(
    q1_m: Num,
    v_m_s: Num,
    acc_m_s2: Num,
    inertia_kgm2: Num,
    weight_coeff_nm: Num,
    a_m: Num,
    b_m: Num,
    h_m: Num,
    xp: ModuleType = math,
) -> Num:
    """Force the boom demands from the rod, N: m q1'' + m' q1'^2 / 2 + M_g k (eq. 10, corrected).

    Eq. 10 has the same inertia terms; its weight term carries xi where cos(alpha) belongs
    (see :func:`paper_load_force_n` for the printed form).
    """
    k = lever_rad_per_m(q1_m, a_m, b_m, xp)
    mass = effective_mass_kg(inertia_kgm2, k)
    moment = weight_coeff_nm * cos_boom_angle(q1_m, a_m, b_m, h_m, xp)  # M_g
    return mass * acc_m_s2 + mass * lever_derivative(q1_m, a_m, b_m, xp) / k * v_m_s * v_m_s + moment * k


@jitable
def paper_load_force_n(
    q1_m: Num,
    v_m_s: Num,
    acc_m_s2: Num,
    inertia_kgm2: Num,
    boom_mass_kg: Num,
    payload_mass_kg: Num,
    boom_length_m: Num,
    g_m_s2: Num,
    a_m: Num,
    b_m: Num,
    xp: ModuleType = math,
) -> Num:
    """F of eq. 10 exactly as printed, N."""
    x = xi(q1_m, a_m, b_m)
    s2 = 1.0 - x * x
    ab = a_m * b_m
    inertia = (
        inertia_kgm2
        / (ab * ab * s2)
        * (acc_m_s2 * q1_m * q1_m + v_m_s * v_m_s * q1_m - x / (ab * s2) * v_m_s * v_m_s * q1_m**3)
    )  # eq. 10, first line
    weight = g_m_s2 * boom_length_m * (payload_mass_kg + 0.5 * boom_mass_kg) * q1_m * x / (ab * xp.sqrt(s2))
    return inertia + weight  # eq. 10, second line


@jitable
def paper_acceleration(
    q1_m: Num,
    v_m_s: Num,
    piston_force_n: Num,
    friction_n: Num,
    spring_n_m: Num,
    inertia_kgm2: Num,
    weight_coeff_nm: Num,
    a_m: Num,
    b_m: Num,
    h_m: Num,
    xp: ModuleType = math,
) -> Num:
    """q1'' exactly as the Fig. 7 listing computes it (eq. 16 with its factor 1/2), m/s^2.

    acceleration = a^2 b^2 (1 - xi^2) / (2 J q^2) * (p S1 - F_mp - (c + M_g/(ab sqrt(1 - xi^2))) q
                   - (1 - xi q^2 / (ab (1 - xi^2))) J q / (a^2 b^2 (1 - xi^2)) v^2 - b v),
    with Theta = arccos(h / b) + arccos(xi) and M_g = (m1/2 + mb) g L1 sin(Theta).
    ``friction_n`` is F_mp + b v (:func:`friction.paper_friction_n`).
    """
    x = xi(q1_m, a_m, b_m)
    s2 = 1.0 - x * x
    ab = a_m * b_m
    theta = xp.acos(h_m / b_m) + xp.acos(x)
    weight = weight_coeff_nm * xp.sin(theta) / (ab * xp.sqrt(s2))
    centripetal = (1.0 - x * q1_m * q1_m / (ab * s2)) * inertia_kgm2 * q1_m / (ab * ab * s2) * v_m_s * v_m_s
    return (
        ab
        * ab
        * s2
        / (2.0 * inertia_kgm2 * q1_m * q1_m)
        * (piston_force_n - friction_n - (spring_n_m + weight) * q1_m - centripetal)
    )  # Fig. 7 listing, eq. 16
