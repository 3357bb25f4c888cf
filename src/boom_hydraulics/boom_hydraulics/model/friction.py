"""Friction of piston and rod seals (the F_mp and b_d terms of eq. 11).

Physical mode uses the LuGre model (Canudas de Wit et al., 1995) with one state, the
bristle deflection: stiction holds (no creep below the breakaway force), sliding follows
the Stribeck curve, and the damping near rest is the stated sigma1 + b_d.

Equations and conventions: docs/model.md, section "Friction".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable

Num = Any  # float or numpy.ndarray


@jitable
def paper_friction_n(velocity_m_s: Num, coulomb_n: Num, viscous_n_s_m: Num) -> Num:
    """F_mp + b_d v: the Fig. 7 listing's friction, a constant force whatever the direction."""
    return coulomb_n + viscous_n_s_m * velocity_m_s


@jitable
def stribeck_decay(velocity_m_s: Num, stribeck_m_s: Num, xp: ModuleType = math) -> Num:
    """exp(-(v / v_st)^2): 1 at rest, 0 sliding fast; how far the Stribeck curve and the seals'
    damping sigma1 have fallen from their values at rest (both take it: one exp per evaluation)."""
    ratio = velocity_m_s / stribeck_m_s
    return xp.exp(-ratio * ratio)


@jitable
def stribeck_level(decay: Num, coulomb_n: Num, static_n: Num) -> Num:
    """g(v) = F_c + (F_s - F_c) exp(-(v / v_st)^2): the sliding friction at speed v, N (Stribeck
    curve), with ``decay`` = exp(-(v / v_st)^2) (:func:`stribeck_decay`)."""
    return coulomb_n + (static_n - coulomb_n) * decay


@jitable
def bristle_rate(velocity_m_s: Num, bristle: Num, level_ratio: Num, presliding_m: Num) -> Num:
    """ds/dt of the LuGre seal model, 1/s, with s = z / z_ba the bristle deflection over the
    presliding displacement (s = 1 is the breakaway deflection).

    LuGre: dz/dt = v - sigma0 |v| z / g(v), sigma0 = F_s / z_ba; so
    ds/dt = (v - |v| s / r(v)) / z_ba, r = g(v) / F_s (1 at rest, F_c / F_s when sliding).
    At rest (v = 0) s does not move: a force below breakaway holds the rod, it never creeps.
    """
    return (velocity_m_s - abs(velocity_m_s) * bristle / level_ratio) / presliding_m


@jitable
def seal_friction_n(
    velocity_m_s: Num,
    bristle: Num,
    bristle_rate_1_s: Num,
    static_n: Num,
    presliding_m: Num,
    damping_n_s_m: Num,
    decay: Num,
    viscous_n_s_m: Num,
) -> Num:
    """LuGre friction force opposing motion, N (positive for positive deflection and velocity).

    F = sigma0 z + sigma1(v) dz/dt + b_d v = F_s s + sigma1 exp(-(v / v_st)^2) z_ba ds/dt + b_d v.
    Sliding steadily, s = r(v) sign(v) and F = g(v) sign(v) + b_d v (the Stribeck curve);
    near rest the seals act as a spring F_s / z_ba in parallel with a damper sigma1 + b_d.
    ``decay`` is exp(-(v / v_st)^2) (:func:`stribeck_decay`).
    """
    sigma1 = damping_n_s_m * decay
    return static_n * bristle + sigma1 * presliding_m * bristle_rate_1_s + viscous_n_s_m * velocity_m_s
