"""The 4/3 proportional valve with its load-holding valve: how a valve drive's pump reaches the chambers.

The spool's four paths (hydraulics.valve_flows) connect the pump's P port and the tank to
the lines of the piston chamber (A) and the rod chamber (B); a pilot-operated check valve
(the load-holding valve) in line A lets oil out of the piston chamber only as far as the
lowering command pilots it open. The valve drives (model/drives: ``VALVE``) call
:func:`paths` with their P-port pressure; what the valve dissipates goes to the energy
ledger as its throttling and leakage (eq. D27).

Equations and conventions: docs/model.md, sections "Valve" and "Supply and relief valves".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import jitable
from .hydraulics import load_holding_flow, orifice_flow, pos, smaller, valve_flows

Num = Any  # float or numpy.ndarray

#: Spool opening towards lowering at which the pilot has fully opened the load-holding valve.
PILOT_FULL_OPENING = 0.05


class Paths(NamedTuple):
    """The valve at one instant (SI)."""

    q_a: Num  # into the piston-chamber line, through the load-holding valve, m^3/s
    q_b: Num  # into the rod-chamber line, m^3/s
    q_in: Num  # what the P paths take from the pump through A and B, m^3/s
    throttling: Num  # W (eq. D27)
    leakage: Num  # W (eq. D27)


@jitable
def losses(
    q_pa: Num,
    q_at: Num,
    q_pb: Num,
    q_bt: Num,
    p_port_pa: Num,
    p_tank_pa: Num,
    p1_pa: Num,
    p2_pa: Num,
    leak_m3_s_pa: Num,
    a_side: Num,
    seat_leak_m3_s_pa: Num,
) -> tuple[Num, Num]:
    """(throttling, leakage) in the 4/3 valve and the load-holding valve, W (eq. D27).

    ``q_pa`` .. ``q_bt`` are the spool's path flows (hydraulics.valve_flows) and ``a_side`` the
    share of the A paths' flow the load-holding valve passes (1, or its pilot opening where
    it checks an outflow). Each path dissipates dp Q, of which G dp^2 is its leakage; the
    closed seat leaks G_seat (p1 - p_t) with the power G_seat (p1 - p_t)^2. Their sum is the
    supply's power less what reaches the cylinder lines ("Supply and relief valves")."""
    dp_pa, dp_at = p_port_pa - p1_pa, p1_pa - p_tank_pa
    dp_pb, dp_bt = p_port_pa - p2_pa, p2_pa - p_tank_pa
    paths = a_side * (dp_pa * q_pa + dp_at * q_at) + dp_pb * q_pb + dp_bt * q_bt
    leakage = (
        leak_m3_s_pa * (a_side * (dp_pa * dp_pa + dp_at * dp_at) + dp_pb * dp_pb + dp_bt * dp_bt)
        + seat_leak_m3_s_pa * dp_at * dp_at
    )
    return paths - leakage + seat_leak_m3_s_pa * dp_at * dp_at, leakage  # eq. D27


@jitable(inline="always")
def paths(opening: Num, p_port_pa: Num, p1_pa: Num, p2_pa: Num, d: Any, xp: ModuleType = math) -> Paths:
    """The valve at spool position ``opening`` with ``p_port_pa`` at its P port (``d``: the
    drives' constants: k_valve, transition2, leak, holding, seat_leak, p_tank)."""
    q_pa, q_at, q_pb, q_bt = valve_flows(
        opening, p_port_pa, d.p_tank, p1_pa, p2_pa, d.k_valve, d.transition2, d.leak, xp
    )
    # the load-holding valve lets oil out of the piston chamber only when the pilot opens it
    lowering = smaller(pos(-opening) / PILOT_FULL_OPENING, 1.0)
    pilot = 1.0 - d.holding + d.holding * lowering * lowering * (3.0 - 2.0 * lowering)  # smoothstep: no kink
    port_a = q_pa - q_at
    seat = d.holding * d.seat_leak
    q_a = load_holding_flow(port_a, pilot, p1_pa, d.p_tank, seat)
    a_side = 1.0 - (1.0 - pilot) * (port_a < 0.0)
    q_in = q_pa * a_side + q_pb  # what the pump delivers through A and B
    throttling, leakage = losses(q_pa, q_at, q_pb, q_bt, p_port_pa, d.p_tank, p1_pa, p2_pa, d.leak, a_side, seat)
    return Paths(q_a, q_pb - q_bt, q_in, throttling, leakage)


@jitable
def laminar_slope(opening: Num, d: Any) -> Num:
    """The steepest dQ/dp of the paths at ``opening`` (laminar region) plus two leaking paths, m^3/(s Pa)."""
    return d.k_laminar * opening + 2.0 * d.leak


# --- the open centre (docs/model.md, "Open-centre valve"; eq. D65-D67) ----------------------


@jitable
def centre_coefficient(flow_m3_s: float, drop_pa: float, transition_pa: float) -> float:
    """K_c of an open centre that passes ``flow_m3_s`` at ``drop_pa`` through the laminar-turbulent
    orifice ("Orifices and the 4/3 valve"): K_c = Q (dp^2 + p_tr^2)^(1/4) / dp, m^3/(s Pa^0.5) (eq. D65)."""
    return flow_m3_s * math.sqrt(math.sqrt(drop_pa * drop_pa + transition_pa * transition_pa)) / drop_pa


@jitable
def centre_opening(opening: Num, d: Any) -> Num:
    """The open centre's share of its full area at spool ``opening``: 1 in neutral, falling
    linearly to 0 at |x| = x_c (``d.centre_closed``), and 0 with a closed centre (eq. D65)."""
    return d.open_centre * pos(1.0 - abs(opening) / d.centre_closed)


@jitable
def centre_flow(opening: Num, p_port_pa: Num, d: Any, xp: ModuleType = math) -> tuple[Num, Num]:
    """(Q_c, its throttling loss): what the open centre passes from the P port to tank at spool
    ``opening``, m^3/s, and (p_P - p_t) Q_c, W (eq. D66; ``d``: the drives' constants: open_centre,
    k_centre, centre_closed, transition2, p_tank). Zero with a closed centre."""
    dp = p_port_pa - d.p_tank
    q = d.k_centre * centre_opening(opening, d) * orifice_flow(1.0, dp, d.transition2, xp)  # eq. D66
    return q, dp * q


@jitable
def centre_slope(opening: Num, d: Any) -> Num:
    """The steepest dQ_c/dp of the open centre at ``opening`` (its laminar region), m^3/(s Pa)."""
    return d.k_centre * centre_opening(opening, d) * d.k_laminar / d.k_valve
