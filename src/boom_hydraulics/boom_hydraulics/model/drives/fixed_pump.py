"""fixed_pump: the paper's circuit (Fig. 6), a fixed pump at constant speed and a main relief at p_n.

The electric motor turns the pump at w_n; it delivers D w_n less its leakage (eq. D1) into
the supply line, a volume V_s with its own pressure state (eq. D13), which the valve's P
paths and the main relief valve drain. The relief cracks at p_n and passes the pump's
full flow at p_n plus its range (eq. D12): with the closed-centre valve closed, the whole
flow goes over it, and the pump draws about p_n Q_max / eta from the battery while the
boom holds (eq. D14). The line cavitates as a chamber does, keeping its oil
(docs/model.md, "Chambers"). With ``valve_centre: open`` the valve's open centre passes the
flow to tank at low pressure in neutral (model/valve.py, eq. D65-D67); under a
``motor_strategy`` other than constant the motor's speed is the drive's second state
(motor_speed, eq. D60-D64).

Equations and conventions: docs/model.md, sections "Drives", "Motor strategies" and
"Open-centre valve".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import chamber_pressure_pa, chamber_state_rate, larger, orifice_pressure_drop, relief_flow
from ..pump import delivered_flow_m3_s
from ..valve import centre_flow, centre_slope, laminar_slope, paths
from . import motor_speed
from .constants import DriveConstants, Supply, pump_point

Num = Any  # float or numpy.ndarray

#: What a plot's legend calls the drive (analysis/labels.py).
LABEL = "fixed pump"
#: The drive's states: the supply line's liquid state z_s (its pressure above the floor), Pa; the
#: motor's speed and idle_stop's demand memory (motor_speed).
STATE_NAMES = ("supply_line_state", *motor_speed.STATE_NAMES)
STATE_SCALES = ("pressure", *motor_speed.STATE_SCALES)
STATE_UNITS = ("Pa", *motor_speed.STATE_UNITS)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = False
#: The supply line is a node an accumulator can sit on: :func:`supply` takes the flow it draws.
SUPPLY_NODE = True


@jitable
def dead_head_pressure_pa(d: DriveConstants) -> float:
    """The line's steady pressure with the valve closed (its leakage neglected), Pa (eq. D14):
    D w_n - G_p (p - p_t) = G_mr (p - p_n)."""
    return (d.displacement * d.speed + d.pump_leak * d.p_tank + d.g_main * d.p_set) / (d.pump_leak + d.g_main)


@jitable
def centre_pressure_pa(geometric_flow_m3_s: Num, d: DriveConstants) -> Num:
    """The line's steady pressure with the spool in neutral and the centre open, Pa (eq. D67): the
    centre passes what the pump delivers, K_c f(p_s - p_t) = D w - G_p (p_s - p_t) (the spool's
    leakage neglected), solved by fixed-point steps on the orifice's inverse (the leakage's share
    G_p dp / D w is well under 1 %)."""
    dp = 0.0 * geometric_flow_m3_s
    for _ in range(4):
        dp = orifice_pressure_drop(d.k_centre, geometric_flow_m3_s - d.pump_leak * dp, d.transition2)  # eq. D67
    return d.p_tank + dp


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The pump runs before the run starts at w_n: the line at its dead-heading pressure (eq. D14), or
    with an open centre at the centre's pressure (eq. D67), Pa (a slower motor brings it down
    within the line's time constant); the motor's speed and demand memory (motor_speed)."""
    w, m = motor_speed.initial_state(d)
    closed = dead_head_pressure_pa(d)
    return (closed + d.open_centre * (centre_pressure_pa(d.displacement * d.speed, d) - closed), w, m)


@jitable
def main_relief_flow_m3_s(p_line_pa: Num, d: DriveConstants) -> Num:
    """Q_mr = G_mr (p_s - p_n) above p_n, to tank, m^3/s (eq. D12)."""
    return relief_flow(p_line_pa, d.p_set, d.g_main)  # eq. D12


@jitable
def node_pressure(z: tuple, d: DriveConstants) -> Num:
    """The supply line's pressure, p_s = max(z_s, p_cav), Pa (eq. D13)."""
    return chamber_pressure_pa(z[0], d.p_cav)


@jitable
def supply(
    z: tuple,
    u: Num,
    opening: Num,
    q1: Num,
    v: Num,
    p1_pa: Num,
    p2_pa: Num,
    d: DriveConstants,
    xp: ModuleType = math,
    q_draw: Num = 0.0,
) -> Supply:
    """The drive at its states ``z`` (the line's state z[0]; the motor's z[1], z[2]): the valve at
    the line's pressure, its open centre if it has one (eq. D66), the line's state rate (eq. D13),
    the pump at the motor's speed (w_n; speed on demand: |x| w_n, eq. D62) and the main relief's
    loss. ``q_draw``: what an accumulator on the line takes from it, m^3/s (eq. A3)."""
    ps = node_pressure(z, d)
    valve = paths(opening, ps, p1_pa, p2_pa, d, xp)
    q_centre, centre_loss = centre_flow(opening, ps, d, xp)  # eq. D66 (0 with a closed centre)
    m = motor_speed.motor(z, opening, abs(opening) * d.speed, d)  # eq. D62: the spool sets the speed
    dp = ps - d.p_tank
    q_pump = delivered_flow_m3_s(d.displacement, m.speed, dp, d.pump_leak)  # eq. D1
    q_relief = main_relief_flow_m3_s(ps, d)
    net = q_pump - valve.q_in - q_relief - q_centre - q_draw
    rate = chamber_state_rate(d.bulk_modulus, d.line_volume, net, 0.0, z[0], d.p_cav)  # eq. D13
    pumped = pump_point(d.displacement, m.speed, dp, q_pump, d, xp)
    zero = 0.0 * dp
    return Supply(
        *(rate, m.speed_rate, m.memory_rate, valve.q_a, valve.q_b, 1.0 + zero, zero, opening + zero, ps),
        *(1.0 * (ps < d.p_set), dp * valve.q_in, pumped.torque + m.torque, m.speed + zero, pumped.hydraulic_power),
        *(pumped.volumetric_loss, pumped.mechanical_loss, dp * q_relief, valve.throttling + centre_loss),
        *(valve.leakage, dp * net, zero, m.rotor_power, zero),
    )


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """The compression of the supply line's oil, V_s (p_s - p_t)^2 / (2 E), and the rotors'
    kinetic energy (motor_speed), J."""
    ps = chamber_pressure_pa(z[0], d.p_cav)
    return d.line_volume * (ps - d.p_tank) * (ps - d.p_tank) / (2.0 * d.bulk_modulus) + motor_speed.energy(z, d)


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s`` (the pressure stands still at the floor), W."""
    dps = s.rate * (z[0] > d.p_cav)
    return d.line_volume * (s.p_supply - d.p_tank) * dps / d.bulk_modulus + motor_speed.energy_rate(z, s.rate2, d)


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """The valve's slopes, and the line: against its relief where it can reach it within this
    step, the pump's leakage and the valve, and against a chamber through the open path,
    G E (1/V_s + 1/V): the two oil springs in series."""
    slope = laminar_slope(opening, d)
    line_stiffness = d.bulk_modulus / d.line_volume
    relief_near = z[0] + line_stiffness * d.max_flow * dt > d.p_set
    centre = centre_slope(opening, d)  # 0 with a closed centre
    line = line_stiffness * (d.g_main * relief_near + d.pump_leak + slope + centre) + slope * larger(stiff1, stiff2)
    return slope, slope, larger(line, motor_speed.fastest_rate(d))
