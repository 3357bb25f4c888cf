"""End stops of the cylinder stroke: Hunt-Crossley contacts.

Equations and conventions: docs/model.md, section "End stops".
"""

from __future__ import annotations

from typing import Any

from ..jit import jitable
from .hydraulics import pos

Num = Any  # float or numpy.ndarray


@jitable
def end_stop_force_n(
    q1_m: Num, velocity_m_s: Num, min_length_m: Num, max_length_m: Num, stiffness_n_m: Num, damping_n_s_m2: Num
) -> Num:
    """Contact force of the end stops on the rod, N (positive extends).

    Hunt-Crossley with a linear spring: F = k d + lambda d d' for a penetration d > 0 below
    the min or above the max length. The damping grows with the penetration, so the force
    is zero at first contact and continuous in time (no jump that would cost the integrator
    its order); the contact only pushes (it never pulls the rod into the stop). An impact at
    speed v keeps the fraction e = 1 - 2/3 (lambda / k) v of its speed (small lambda v / k).
    """
    d_low = pos(min_length_m - q1_m)
    d_high = pos(q1_m - max_length_m)
    push_out = pos(stiffness_n_m * d_low - damping_n_s_m2 * d_low * velocity_m_s)
    push_in = pos(stiffness_n_m * d_high + damping_n_s_m2 * d_high * velocity_m_s)
    return push_out - push_in


@jitable
def end_stop_energy_j(q1_m: Num, min_length_m: Num, max_length_m: Num, stiffness_n_m: Num) -> Num:
    """Elastic energy stored in the end stops, k d^2 / 2, J."""
    d_low = pos(min_length_m - q1_m)
    d_high = pos(q1_m - max_length_m)
    return 0.5 * stiffness_n_m * (d_low * d_low + d_high * d_high)
