"""load_sensing: a variable pump whose pressure follows the fed port's pressure plus a margin.

The load-sensing line reads the working port the spool connects to the pump (A lifting, B
lowering), through a signal opening that opens with the first 5 % of the spool's stroke
(eq. D15, D16); with the spool closed it is vented to tank, and the pump idles at the
margin. The pump's pressure follows the load plus the margin, at most p_n, with the
pump's own lag (eq. D17, D18), delivers on demand, and falls where the open path would
take more than its maximum flow, as the pressure-compensated pump's does (eq. D19). The
meter-in throttling is the margin; the meter-out throttling on lowering remains.

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import smaller, smoothstep
from .constants import DriveConstants, Supply
from .pressure_compensated import on_demand
from .pressure_compensated import port_pressure_pa as _pump_port_pressure_pa

Num = Any  # float or numpy.ndarray

#: The drive's one state: the pump's pressure setting, which follows the load with a lag, Pa.
STATE_NAMES = ("drive_state",)
STATE_SCALES = ("pressure",)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True

#: Spool opening at which the load-sensing signal port is fully open (eq. D15).
SIGNAL_FULL_OPENING = 0.05


@jitable
def initial_state(d: DriveConstants) -> float:
    """The pump idles at the margin over tank pressure with the spool closed, Pa."""
    return d.p_tank + d.ls_margin


@jitable
def load_pressure_pa(opening: Num, p1_pa: Num, p2_pa: Num, p_tank_pa: Num) -> Num:
    """The load-sensing signal: the fed port's pressure through the signal opening, Pa (eq. D15, D16).

    w = smoothstep(|x| / x_LS); p_LS = p_t + w (p_fed - p_t), p_fed = p1 for x > 0, p2 for x < 0."""
    signal = smoothstep(abs(opening) / SIGNAL_FULL_OPENING)  # eq. D15
    fed = p1_pa * (opening > 0.0) + p2_pa * (opening <= 0.0)
    return p_tank_pa + signal * (fed - p_tank_pa)  # eq. D16


@jitable
def target_pressure_pa(opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants) -> Num:
    """p* = min(p_LS + margin, p_n): what the pump's pressure heads for, Pa (eq. D17)."""
    return smaller(load_pressure_pa(opening, p1_pa, p2_pa, d.p_tank) + d.ls_margin, d.p_set)  # eq. D17


#: The valve's P-port pressure: the pump's, or less at its flow limit, Pa (eq. D19): the
#: pressure-compensated pump's law, set to this pump's pressure z.
port_pressure_pa = _pump_port_pressure_pa


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
    """The supply side: the pump's pressure lag (eq. D18), delivering on demand (eq. D4)."""
    rate = (target_pressure_pa(opening, p1_pa, p2_pa, d) - z) * d.ls_inv_tau  # eq. D18
    return on_demand(rate, p_port_pa, q_valve_in_m3_s, d)
