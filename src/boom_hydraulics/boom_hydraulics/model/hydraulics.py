"""Hydraulic elements: orifice, chamber, 4/3 spool valve, relief valve, supply (eq. 12-15, 17).

Functions work on floats (``xp=math``) and numpy arrays (``xp=numpy``); branches are
written with operators (``pos(z) = max(z, 0)`` as ``(z + |z|) / 2``) so both share one code.

Equations and conventions: docs/model.md, sections "Chambers; Orifices and the 4/3 valve; Supply and relief valves".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable

Num = Any  # float or numpy.ndarray

#: Added to an open area coefficient so that a closed valve divides by no zero, m^3/(s Pa^0.5).
_TINY_COEFF = 1e-30


@jitable
def pos(z: Num) -> Num:
    """max(z, 0) for floats and arrays alike."""
    return 0.5 * (z + abs(z))


@jitable
def smaller(x: Num, y: Num) -> Num:
    """min(x, y) for floats and arrays alike (exact, also when y is huge; y finite)."""
    return x + (y - x) * (y < x)


@jitable
def larger(x: Num, y: Num) -> Num:
    """max(x, y) for floats and arrays alike."""
    return x + pos(y - x)


@jitable
def smoothstep(s: Num) -> Num:
    """0 for s <= 0, 1 for s >= 1, and 3 s^2 - 2 s^3 between: a switch without a kink."""
    clipped = smaller(pos(s), 1.0)
    return clipped * clipped * (3.0 - 2.0 * clipped)


@jitable
def orifice_coefficient(discharge_coefficient: Num, area_m2: Num, density_kg_m3: Num) -> Num:
    """K = mu f sqrt(2 / rho), so that turbulent flow is Q = K sqrt(dp), m^3/(s Pa^0.5) (eq. 14)."""
    return discharge_coefficient * area_m2 * (2.0 / density_kg_m3) ** 0.5


@jitable
def turbulent_orifice_flow(k: Num, dp_pa: Num, xp: ModuleType = math) -> Num:
    """Q = mu f sqrt(2 |dp| / rho) sign(dp), m^3/s: the paper's orifice law (eq. 14, 15).

    Its derivative dQ/d(dp) is infinite at dp = 0 (stiff near equal pressures).
    """
    return k * xp.copysign(xp.sqrt(abs(dp_pa)), dp_pa)  # eq. 14


@jitable
def orifice_flow(k: Num, dp_pa: Num, transition_pa2: Num, xp: ModuleType = math) -> Num:
    """Orifice flow with a laminar-turbulent transition, m^3/s.

    Q = K dp / (dp^2 + p_tr^2)^(1/4): turbulent K sqrt(|dp|) sign(dp) for |dp| >> p_tr,
    laminar K dp / sqrt(p_tr) below, so dQ/d(dp) stays finite (at most K / sqrt(p_tr)).
    This is the smooth orifice of Simscape Fluids' orifice blocks, with p_tr given directly.
    ``transition_pa2`` is p_tr^2.
    """
    return k * dp_pa / xp.sqrt(xp.sqrt(dp_pa * dp_pa + transition_pa2))  # (..)^(1/4); pow is slow on arrays


@jitable
def orifice_pressure_drop(k: Num, flow_m3_s: Num, transition_pa2: Num, xp: ModuleType = math) -> Num:
    """Inverse of :func:`orifice_flow` for flow >= 0: the dp that passes ``flow_m3_s``, Pa.

    With r = Q / K, dp^4 = r^4 (dp^2 + p_tr^2), so dp^2 = r^4 / 2 (1 + sqrt(1 + 4 p_tr^2 / r^4)).
    """
    r = flow_m3_s / k
    r4 = r * r * r * r
    return xp.sqrt(0.5 * r4 * (1.0 + xp.sqrt(1.0 + 4.0 * transition_pa2 / r4)))


@jitable
def chamber_pressure_rate(bulk_modulus_pa: Num, volume_m3: Num, inflow_m3_s: Num, volume_rate_m3_s: Num) -> Num:
    """dp/dt = E / V (Q_in - dV/dt), Pa/s (eq. 12 for the piston chamber, eq. 13 for the rod one)."""
    return bulk_modulus_pa / volume_m3 * (inflow_m3_s - volume_rate_m3_s)  # eq. 12, 13


@jitable
def chamber_pressure_pa(liquid_state_pa: Num, floor_pa: Num) -> Num:
    """Pressure of a cavitating chamber from its state z: max(z, p_cav), Pa.

    Above the floor z is the pressure; below it, z measures the void (gas and vapour)
    volume V_void = (p_cav - z) V / E while the pressure stays at the floor.
    """
    return floor_pa + pos(liquid_state_pa - floor_pa)


@jitable
def chamber_state_rate(
    bulk_modulus_pa: Num,
    volume_m3: Num,
    inflow_m3_s: Num,
    volume_rate_m3_s: Num,
    liquid_state_pa: Num,
    floor_pa: Num,
) -> Num:
    """dz/dt of a chamber that cavitates without creating or losing oil, Pa/s.

    Full of liquid (z >= p_cav): dz/dt = E / V (Q_in - dV/dt), eq. 12 / 13.
    With a void (z < p_cav): the void takes the difference, dV_void/dt = dV/dt - Q_in, and
    z = p_cav - E V_void / V follows it: dz/dt = E / V (Q_in - dV/dt) + (p_cav - z) (dV/dt) / V.
    The extra term is zero at the floor, so the rate is continuous. An inflow first refills
    the void; the pressure rises only once it is gone (mass-conserving, as the cavitating
    chambers of Simscape Fluids and Hopsan).
    """
    void_term = pos(floor_pa - liquid_state_pa) * volume_rate_m3_s / volume_m3
    return chamber_pressure_rate(bulk_modulus_pa, volume_m3, inflow_m3_s, volume_rate_m3_s) + void_term


@jitable
def void_volume_m3(bulk_modulus_pa: Num, volume_m3: Num, liquid_state_pa: Num, floor_pa: Num) -> Num:
    """Volume of the void in a cavitating chamber, (p_cav - z) V / E where z < p_cav, m^3."""
    return pos(floor_pa - liquid_state_pa) * volume_m3 / bulk_modulus_pa


@jitable
def load_holding_flow(
    port_inflow_m3_s: Num, pilot_opening: Num, chamber_pa: Num, tank_pa: Num, seat_leakage_m3_s_pa: Num
) -> Num:
    """Flow into a chamber through a pilot-operated check (load-holding) valve, m^3/s.

    Inflow (from the spool) passes freely; outflow passes in proportion to the pilot
    opening (0: closed, the chamber is sealed; 1: fully open). The closed seat leaks
    G_seat (p - p_tank) to tank in parallel.
    """
    return (
        pos(port_inflow_m3_s) - pilot_opening * pos(-port_inflow_m3_s) - seat_leakage_m3_s_pa * (chamber_pa - tank_pa)
    )


@jitable
def relief_flow(pressure_pa: Num, cracking_pa: Num, conductance_m3_s_pa: Num) -> Num:
    """Port relief valve to tank: Q = G (p - p_crack) above its cracking pressure, m^3/s.

    G = rated flow / pressure range, so the valve passes its rated flow at p_crack + range.
    """
    return conductance_m3_s_pa * pos(pressure_pa - cracking_pa)


@jitable
def valve_flows(
    opening: Num,
    p_supply_pa: Num,
    p_tank_pa: Num,
    p1_pa: Num,
    p2_pa: Num,
    k_max: Num,
    transition_pa2: Num,
    leak_m3_s_pa: Num,
    xp: ModuleType = math,
) -> tuple[Num, Num, Num, Num]:
    """Flows through the four paths of a critically lapped 4/3 proportional valve, m^3/s.

    Opening x in [-1, 1]: x > 0 opens P->A and B->T, x < 0 opens P->B and A->T, each to
    the area |x| * f_max (eq. 17 gives f_max); every path also leaks laminarly (G dp).
    Returns (Q_PA, Q_AT, Q_PB, Q_BT), each positive in the named direction
    (eq. 14 for the pump paths, eq. 15 for the tank paths).
    """
    x_plus = pos(opening)
    x_minus = x_plus - opening
    dp_pa, dp_at = p_supply_pa - p1_pa, p1_pa - p_tank_pa
    dp_pb, dp_bt = p_supply_pa - p2_pa, p2_pa - p_tank_pa
    q_pa = k_max * x_plus * orifice_flow(1.0, dp_pa, transition_pa2, xp) + leak_m3_s_pa * dp_pa
    q_at = k_max * x_minus * orifice_flow(1.0, dp_at, transition_pa2, xp) + leak_m3_s_pa * dp_at
    q_pb = k_max * x_minus * orifice_flow(1.0, dp_pb, transition_pa2, xp) + leak_m3_s_pa * dp_pb
    q_bt = k_max * x_plus * orifice_flow(1.0, dp_bt, transition_pa2, xp) + leak_m3_s_pa * dp_bt
    return q_pa, q_at, q_pb, q_bt


@jitable
def supply_pressure(
    opening: Num,
    p_set_pa: Num,
    p1_pa: Num,
    p2_pa: Num,
    k_max: Num,
    transition_pa2: Num,
    pump_max_flow_m3_s: Num,
    xp: ModuleType = math,
) -> Num:
    """Pressure at the valve's P port from a pressure-compensated pump, Pa.

    The pump holds ``p_set_pa`` while the valve takes no more than its maximum flow; when
    the open path would take more, the supply pressure falls to the value at which the
    path passes exactly the maximum flow (leakage neglected in this balance).
    """
    x_abs = abs(opening)
    p_fed = (pos(opening) * p1_pa + pos(-opening) * p2_pa) / (x_abs + _TINY_COEFF)
    dp_max = orifice_pressure_drop(k_max * x_abs + _TINY_COEFF, pump_max_flow_m3_s, transition_pa2, xp)
    return smaller(p_set_pa, p_fed + dp_max)
