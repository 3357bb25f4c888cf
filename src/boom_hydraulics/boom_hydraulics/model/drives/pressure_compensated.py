"""pressure_compensated: a variable pump at constant speed that holds p_n and delivers on demand.

Today's source, kept as the reference: the P port sees p_n, or less where the open path
would take more than the pump's maximum flow (docs/model.md, "Supply and relief valves").
The compensator strokes the pump to deliver what the valve takes plus the pump's own
leakage (eq. D4), so the pump draws shaft power even while the boom holds (the standby
loss G_p p_n^2 and its friction). The drive's first state is a constant p_n (rate 0), as
every valve drive's first state is its pressure; the second and third are its motor's
(motor_speed: ``motor_strategy``), which stand still at the default constant speed.

Equations and conventions: docs/model.md, sections "Drives" and "Motor strategies".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import larger, smaller, supply_pressure
from ..pump import stroke_for_flow_m3_rad
from ..valve import laminar_slope, paths
from . import motor_speed
from .constants import DriveConstants, Supply, in_use, pump_point

Num = Any  # float or numpy.ndarray

#: What a plot's legend calls the drive (analysis/labels.py).
LABEL = "pressure compensated"
#: The drive's states: the pressure the compensator holds (a constant here), Pa; the motor's
#: speed and idle_stop's demand memory (motor_speed; standing still under the constant strategy).
STATE_NAMES = ("supply_pressure", *motor_speed.STATE_NAMES)
STATE_SCALES = ("pressure", *motor_speed.STATE_SCALES)
STATE_UNITS = ("Pa", *motor_speed.STATE_UNITS)
#: The speed below which the stroke's division and the flow limit take this speed: a stopped
#: pump holds no pressure (its P port is at tank pressure), so it gives no torque whatever its
#: stroke, rad/s.
STOPPED_RAD_S = 1e-6
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = True


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The compensator's pressure p_n, Pa; the motor's speed and demand memory (motor_speed)."""
    w, m = motor_speed.initial_state(d)
    return (d.p_set, w, m)


@jitable
def port_pressure_pa(z: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """The valve's P-port pressure of a pump set to z: z, or less where the open path would take more
    than the pump's maximum flow, Pa ("Supply and relief valves"; eq. D19)."""
    return supply_pressure(opening, z, p1_pa, p2_pa, d.k_valve, d.transition2, d.max_flow, xp)


@jitable
def port_pressure_at_speed_pa(
    z: Num, speed: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Num:
    """The P-port pressure of a pump set to z at full displacement and speed w: eq. D19 with its
    geometric flow D w in place of Q_max, and at most its dead-heading pressure against its own
    leakage, p_t + D w / G_p (eq. D62), Pa. At w_n it is at least :func:`port_pressure_pa`'s; a
    stopped pump holds none."""
    flow = d.displacement * larger(speed, STOPPED_RAD_S)  # the orifice's inverse of no flow is 0/0
    dead_head = d.p_tank + flow / d.pump_leak
    return smaller(supply_pressure(opening, z, p1_pa, p2_pa, d.k_valve, d.transition2, flow, xp), dead_head)


@jitable(inline="always")
def on_demand(
    rate: Num,
    p_pump_pa: Num,
    z: tuple,
    opening: Num,
    p1_pa: Num,
    p2_pa: Num,
    d: DriveConstants,
    xp: ModuleType = math,
) -> Supply:
    """A variable pump set to ``p_pump_pa`` (its state's rate ``rate``) on the 4/3 valve at spool
    position ``opening``, its motor run by the set's strategy (motor_speed; the motor's states in
    ``z``): the P port at the pump's pressure or below it at its flow limit (eq. D19), the pump
    stroked to deliver what the valve's P paths take plus its leakage (eq. D4). At constant speed
    that is all; with speed on demand the motor heads for the speed at which the full
    displacement delivers what the valve would take at full speed, (Q_P + G_p dp) / D (eq. D62),
    and the P port sees the flow limit and the dead-heading pressure of the pump's speed."""
    constant, _, _ = motor_speed.flags(d)
    variable = 1.0 - constant  # (a set whose motor turns at constant speed skips what follows its speed)
    ps = port_pressure_pa(p_pump_pa, opening, p1_pa, p2_pa, d, xp)
    required = 0.0 * ps
    if in_use(variable):
        wanted = paths(opening, ps, p1_pa, p2_pa, d, xp)
        required = (wanted.q_in + d.pump_leak * (ps - d.p_tank)) / d.displacement  # eq. D62
    m = motor_speed.motor(z, opening, required, d)
    if in_use(variable):
        ps = constant * ps + variable * port_pressure_at_speed_pa(p_pump_pa, m.speed, opening, p1_pa, p2_pa, d, xp)
    valve = paths(opening, ps, p1_pa, p2_pa, d, xp)
    dp = ps - d.p_tank
    stroke = stroke_for_flow_m3_rad(valve.q_in, larger(m.speed, STOPPED_RAD_S), dp, d.pump_leak)  # eq. D4
    pumped = pump_point(stroke, m.speed, dp, valve.q_in, d, xp)
    zero = 0.0 * dp
    return Supply(
        *(rate + zero, m.speed_rate, m.memory_rate, valve.q_a, valve.q_b, 1.0 + zero, zero, opening + zero, ps),
        *(1.0 * (ps < p_pump_pa), dp * valve.q_in, pumped.torque + m.torque, m.speed + zero, pumped.hydraulic_power),
        *(pumped.volumetric_loss, pumped.mechanical_loss, zero, valve.throttling, valve.leakage),
        *(zero, zero, m.rotor_power, zero),
    )


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The drive at its states ``z``, command ``u`` and spool position ``opening``: the pump
    holds p_n and delivers what the valve takes; its pressure setting stands still."""
    return on_demand(0.0, d.p_set, z, opening, p1_pa, p2_pa, d, xp)


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the drive stores beside the chambers, J: its rotors' kinetic energy (motor_speed)."""
    return motor_speed.energy(z, d)


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s``, W."""
    return motor_speed.energy_rate(z, s.rate2, d)


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """(dQ/dp the drive's paths give line A, line B, m^3/(s Pa); the fastest rate of its own
    states, 1/s) at spool ``opening``: the valve's laminar slope (stepping.stiffness_rate)."""
    slope = laminar_slope(opening, d)
    return slope, slope, motor_speed.fastest_rate(d) + 0.0 * slope
