"""fixed_pump: the paper's circuit (Fig. 6), a fixed pump at constant speed and a main relief at p_n.

The electric motor turns the pump at w_n; it delivers D w_n less its leakage (eq. D1) into
the supply line, a volume V_s with its own pressure state (eq. D13), which the valve's P
paths and the main relief valve drain. The relief cracks at p_n and passes the pump's
full flow at p_n plus its range (eq. D12): with the closed-centre valve closed, the whole
flow goes over it, and the pump draws about p_n Q_max / eta from the battery while the
boom holds (eq. D14). The line cavitates as a chamber does, keeping its oil
(docs/model.md, "Chambers").

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import chamber_pressure_pa, chamber_state_rate, relief_flow
from ..pump import delivered_flow_m3_s
from .constants import DriveConstants, Supply

Num = Any  # float or numpy.ndarray

#: The drive's one state: the supply line's liquid state z_s (its pressure above the floor), Pa.
STATE_NAMES = ("drive_state",)
STATE_SCALES = ("pressure",)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True


@jitable
def dead_head_pressure_pa(d: DriveConstants) -> float:
    """The line's steady pressure with the valve closed (its leakage neglected), Pa (eq. D14):
    D w_n - G_p (p - p_t) = G_mr (p - p_n)."""
    return (d.displacement * d.speed + d.pump_leak * d.p_tank + d.g_main * d.p_set) / (d.pump_leak + d.g_main)


@jitable
def initial_state(d: DriveConstants) -> float:
    """The pump runs before the run starts: the line at its dead-heading pressure, Pa."""
    return dead_head_pressure_pa(d)


@jitable
def port_pressure_pa(z: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """The valve's P-port pressure: the supply line's, Pa."""
    return chamber_pressure_pa(z, d.p_cav)


@jitable
def main_relief_flow_m3_s(p_line_pa: Num, d: DriveConstants) -> Num:
    """Q_mr = G_mr (p_s - p_n) above p_n, to tank, m^3/s (eq. D12)."""
    return relief_flow(p_line_pa, d.p_set, d.g_main)  # eq. D12


@jitable
def supply(
    z: Num,
    p_port_pa: Num,
    opening: Num,
    p1_pa: Num,
    p2_pa: Num,
    q_valve_in_m3_s: Num,
    d: DriveConstants,
    xp: ModuleType = math,
) -> Supply:
    """The supply side when the valve's P paths take ``q_valve_in_m3_s``: the line's state rate
    (eq. D13), the pump at w_n and the relief's loss."""
    dp = p_port_pa - d.p_tank
    q_pump = delivered_flow_m3_s(d.displacement, d.speed, dp, d.pump_leak)  # eq. D1
    q_relief = main_relief_flow_m3_s(p_port_pa, d)
    net = q_pump - q_valve_in_m3_s - q_relief
    rate = chamber_state_rate(d.bulk_modulus, d.line_volume, net, 0.0, z, d.p_cav)  # eq. D13
    zero = 0.0 * z
    return Supply(rate, d.displacement + zero, d.speed + zero, dp, q_pump, dp * q_relief, dp * net, zero, zero)
