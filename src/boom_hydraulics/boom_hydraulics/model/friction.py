"""Friction of piston and rod seals (the F_mp and b_d terms of eq. 11).

Equations and conventions: docs/model.md, section "Friction".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

Num = Any  # float or numpy.ndarray


def paper_friction_n(velocity_m_s: Num, coulomb_n: Num, viscous_n_s_m: Num) -> Num:
    """F_mp + b_d v: the Fig. 7 listing's friction, a constant force whatever the direction."""
    return coulomb_n + viscous_n_s_m * velocity_m_s


def seal_friction_n(
    velocity_m_s: Num,
    coulomb_n: Num,
    static_n: Num,
    stribeck_m_s: Num,
    smoothing_m_s: Num,
    viscous_n_s_m: Num,
    xp: ModuleType = math,
) -> Num:
    """Friction force opposing motion, N (positive for positive velocity).

    F = (F_c + (F_s - F_c) exp(-(v / v_st)^2)) tanh(v / v_sm) + b_d v:
    Coulomb friction regularised by tanh over v_sm, a Stribeck rise to the breakaway
    force F_s near rest, and viscous friction.
    """
    ratio = velocity_m_s / stribeck_m_s
    level = coulomb_n + (static_n - coulomb_n) * xp.exp(-ratio * ratio)
    return level * xp.tanh(velocity_m_s / smoothing_m_s) + viscous_n_s_m * velocity_m_s
