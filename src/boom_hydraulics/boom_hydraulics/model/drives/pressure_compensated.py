"""pressure_compensated: a variable pump at constant speed that holds p_n and delivers on demand.

Today's source, kept as the reference: the P port sees p_n, or less where the open path
would take more than the pump's maximum flow (docs/model.md, "Supply and relief valves").
The compensator strokes the pump to deliver what the valve takes plus the pump's own
leakage (eq. D4), so the pump draws shaft power even while the boom holds (the standby
loss G_p p_n^2 and its friction). The drive's state is a constant p_n (rate 0): every
valve drive has one state, so that they share one state layout.

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import supply_pressure
from ..pump import stroke_for_flow_m3_rad
from .constants import DriveConstants, Supply

Num = Any  # float or numpy.ndarray

#: The drive's one state: the pressure the compensator holds (a constant here), Pa.
STATE_NAMES = ("drive_state",)
STATE_SCALES = ("pressure",)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True


@jitable
def initial_state(d: DriveConstants) -> float:
    """The compensator's pressure p_n, Pa."""
    return d.p_set


@jitable
def port_pressure_pa(z: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """The valve's P-port pressure of a pump set to z: z, or less where the open path would take more
    than the pump's maximum flow, Pa ("Supply and relief valves"; eq. D19)."""
    return supply_pressure(opening, z, p1_pa, p2_pa, d.k_valve, d.transition2, d.max_flow, xp)


@jitable
def on_demand(rate: Num, p_port_pa: Num, q_valve_in_m3_s: Num, d: DriveConstants) -> Supply:
    """The supply side of a variable pump at w_n that delivers what the valve's P paths take,
    ``q_valve_in_m3_s`` at ``p_port_pa``, stroked for it plus its leakage (eq. D4); ``rate`` is
    its state's."""
    dp = p_port_pa - d.p_tank
    stroke = stroke_for_flow_m3_rad(q_valve_in_m3_s, d.speed, dp, d.pump_leak)  # eq. D4
    zero = 0.0 * dp
    return Supply(rate + zero, stroke, d.speed + zero, dp, q_valve_in_m3_s, zero, zero, zero, zero)


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
    """The supply side when the valve's P paths take ``q_valve_in_m3_s`` at ``p_port_pa``: the
    pump delivers exactly that; its pressure setting stands still."""
    return on_demand(0.0, p_port_pa, q_valve_in_m3_s, d)
