"""load_sensing: a variable pump whose pressure follows the fed port's pressure plus a margin.

The load-sensing line reads the working port the spool connects to the pump (A lifting, B
lowering), through a signal opening that opens with the first 5 % of the spool's stroke
(eq. D15, D16); with the spool closed it is vented to tank, and the pump idles at the
margin. The pump's pressure follows the load plus the margin, at most p_n, with the
pump's own lag (eq. D17, D18), delivers on demand, and falls where the open path would
take more than its maximum flow, as the pressure-compensated pump's does (eq. D19). The
meter-in throttling is the margin; the meter-out throttling on lowering remains. Its motor
runs as ``motor_strategy`` says, as pressure_compensated's does (motor_speed).

Equations and conventions: docs/model.md, sections "Drives" and "Motor strategies".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import larger, smaller, smoothstep
from . import motor_speed
from .constants import DriveConstants, Supply
from .pressure_compensated import energy, energy_rate, on_demand
from .pressure_compensated import stiffness as _valve_stiffness

Num = Any  # float or numpy.ndarray

#: What a plot's legend calls the drive (analysis/labels.py).
LABEL = "load sensing"
#: The drive's states: the pump's pressure setting, which follows the load with a lag, Pa; the
#: motor's speed and idle_stop's demand memory (motor_speed).
STATE_NAMES = ("pump_pressure", *motor_speed.STATE_NAMES)
STATE_SCALES = ("pressure", *motor_speed.STATE_SCALES)
STATE_UNITS = ("Pa", *motor_speed.STATE_UNITS)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = False

#: Spool opening at which the load-sensing signal port is fully open (eq. D15).
SIGNAL_FULL_OPENING = 0.05

__all__ = ("energy", "energy_rate", "initial_state", "stiffness", "supply")


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The pump idles at the margin over tank pressure with the spool closed, Pa; the motor's speed
    and demand memory (motor_speed)."""
    w, m = motor_speed.initial_state(d)
    return (d.p_tank + d.ls_margin, w, m)


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


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The drive at its states ``z`` (the pump's pressure z[0]): the pressure lag (eq. D18), the
    P port at the pump's pressure or below it at its flow limit (eq. D19), delivering on
    demand (eq. D4)."""
    rate = (target_pressure_pa(opening, p1_pa, p2_pa, d) - z[0]) * d.ls_inv_tau  # eq. D18
    return on_demand(rate, z[0], z, opening, p1_pa, p2_pa, d, xp)


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """The valve's slopes, and the pump's pressure lag or its motor's states (as pressure_compensated.stiffness)."""
    g_a, g_b, motor = _valve_stiffness(z, u, opening, stiff1, stiff2, dt, d, xp)
    return g_a, g_b, larger(d.ls_inv_tau + 0.0 * g_a, motor)
