"""End stops of the cylinder stroke as stiff one-sided spring-dampers.

Equations and conventions: docs/model.md, section "End stops".
"""

from __future__ import annotations

from typing import Any

from .hydraulics import pos

Num = Any  # float or numpy.ndarray


def end_stop_force_n(
    q1_m: Num, velocity_m_s: Num, min_length_m: Num, max_length_m: Num, stiffness_n_m: Num, damping_n_s_m: Num
) -> Num:
    """Contact force of the end stops on the rod, N (positive extends).

    Penetration d below min or above max length gives k d plus damping c d', and the
    contact only pushes (it never pulls the rod back into the stop).
    """
    d_low = min_length_m - q1_m
    d_high = q1_m - max_length_m
    push_out = pos(stiffness_n_m * d_low - damping_n_s_m * velocity_m_s) * (d_low > 0.0)
    push_in = pos(stiffness_n_m * d_high + damping_n_s_m * velocity_m_s) * (d_high > 0.0)
    return push_out - push_in
