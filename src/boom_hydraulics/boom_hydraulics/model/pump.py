"""A displacement pump, which is also a motor when the oil drives it: flow, shaft torque, losses.

Signs: the pressure rise dp is outlet minus inlet pressure, the speed w > 0 turns the pump
forwards (oil from inlet to outlet), the displacement D >= 0. Pumping, w dp > 0 and the
shaft gives power; as a motor (the EHA lowering the boom), w dp < 0 and the shaft takes it.
The losses are positive in both directions:

- volumetric: the leakage G_p dp across the pump (eq. D1, D3);
- hydro-mechanical: a friction torque c_f |D dp| against the rotation (eq. D2, D3).

Equations and conventions: docs/model.md, section "Pump".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable

Num = Any  # float or numpy.ndarray

#: Shaft speed below which the friction torque fades with the speed: sign(w) smoothed as
#: w / sqrt(w^2 + w_f^2), so that the torque stays continuous through standstill, rad/s.
FRICTION_SPEED_RAD_S = 1.0


@jitable
def leakage_conductance(volumetric_efficiency: float, max_flow_m3_s: float, rated_dp_pa: float) -> float:
    """G_p = (1 - eta_v) Q_max / dp_n: the leakage that gives ``volumetric_efficiency`` at the
    rated pressure rise and the pump's full geometric flow, m^3/(s Pa) (eq. D1)."""
    return (1.0 - volumetric_efficiency) * max_flow_m3_s / rated_dp_pa


@jitable
def torque_loss_ratio(hydromechanical_efficiency: float) -> float:
    """c_f = 1 / eta_hm - 1: the friction torque over D |dp| that gives ``hydromechanical_efficiency``
    when pumping (eq. D2). As a motor the pump then gives 1 - c_f of D |dp|."""
    return 1.0 / hydromechanical_efficiency - 1.0


@jitable
def delivered_flow_m3_s(displacement_m3_rad: Num, speed_rad_s: Num, dp_pa: Num, leakage_m3_s_pa: Num) -> Num:
    """Q = D w - G_p dp: the flow out of the outlet, m^3/s (eq. D1)."""
    return displacement_m3_rad * speed_rad_s - leakage_m3_s_pa * dp_pa  # eq. D1


@jitable
def shaft_torque_n_m(
    displacement_m3_rad: Num, speed_rad_s: Num, dp_pa: Num, torque_loss: Num, xp: ModuleType = math
) -> Num:
    """T = D dp + c_f |D dp| w / sqrt(w^2 + w_f^2): the torque the shaft must give, N m (eq. D2).

    Pumping it is D dp (1 + c_f); driven by the oil (dp > 0, w < 0) it is D dp (1 - c_f) on
    the far side of standstill: the friction always opposes the rotation.
    """
    ideal = displacement_m3_rad * dp_pa
    direction = speed_rad_s / xp.sqrt(speed_rad_s * speed_rad_s + FRICTION_SPEED_RAD_S * FRICTION_SPEED_RAD_S)
    return ideal + torque_loss * abs(ideal) * direction  # eq. D2


@jitable
def volumetric_loss_w(dp_pa: Num, leakage_m3_s_pa: Num) -> Num:
    """G_p dp^2: the power the leakage takes, W (eq. D3)."""
    return leakage_m3_s_pa * dp_pa * dp_pa  # eq. D3


@jitable
def mechanical_loss_w(
    displacement_m3_rad: Num, speed_rad_s: Num, dp_pa: Num, torque_loss: Num, xp: ModuleType = math
) -> Num:
    """(T - D dp) w: the power the friction torque takes, W, never negative (eq. D3)."""
    torque = shaft_torque_n_m(displacement_m3_rad, speed_rad_s, dp_pa, torque_loss, xp)
    return (torque - displacement_m3_rad * dp_pa) * speed_rad_s  # eq. D3


@jitable
def stroke_for_flow_m3_rad(flow_m3_s: Num, speed_rad_s: Num, dp_pa: Num, leakage_m3_s_pa: Num) -> Num:
    """D = (Q + G_p dp) / w: the displacement a variable pump at speed w sets to deliver Q
    (its compensator strokes it to cover the leakage too), m^3/rad (eq. D4)."""
    return (flow_m3_s + leakage_m3_s_pa * dp_pa) / speed_rad_s  # eq. D4
