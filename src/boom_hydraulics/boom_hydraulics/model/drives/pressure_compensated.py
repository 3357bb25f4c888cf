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
from ..valve import laminar_slope, paths
from .constants import DriveConstants, Supply, pump_point

Num = Any  # float or numpy.ndarray

#: The drive's one state: the pressure the compensator holds (a constant here), Pa.
STATE_NAMES = ("supply_pressure",)
STATE_SCALES = ("pressure",)
STATE_UNITS = ("Pa",)
#: The drive feeds the cylinder through the 4/3 valve.
VALVE = True
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = True


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The compensator's pressure p_n, Pa."""
    return (d.p_set, 0.0, 0.0)


@jitable
def port_pressure_pa(z: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """The valve's P-port pressure of a pump set to z: z, or less where the open path would take more
    than the pump's maximum flow, Pa ("Supply and relief valves"; eq. D19)."""
    return supply_pressure(opening, z, p1_pa, p2_pa, d.k_valve, d.transition2, d.max_flow, xp)


@jitable(inline="always")
def on_demand(
    rate: Num, p_pump_pa: Num, opening: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """A variable pump at w_n set to ``p_pump_pa`` (its state's rate ``rate``) on the 4/3 valve
    at spool position ``opening``: the P port at the pump's pressure or below it at its flow
    limit (eq. D19), the pump stroked to deliver what the valve's P paths take plus its
    leakage (eq. D4)."""
    ps = port_pressure_pa(p_pump_pa, opening, p1_pa, p2_pa, d, xp)
    valve = paths(opening, ps, p1_pa, p2_pa, d, xp)
    dp = ps - d.p_tank
    stroke = stroke_for_flow_m3_rad(valve.q_in, d.speed, dp, d.pump_leak)  # eq. D4
    pumped = pump_point(stroke, d.speed, dp, valve.q_in, d, xp)
    zero = 0.0 * dp
    return Supply(
        *(rate + zero, zero, zero, valve.q_a, valve.q_b, 1.0 + zero, zero, opening + zero, ps),
        *(1.0 * (ps < p_pump_pa), dp * valve.q_in, pumped.torque, d.speed + zero, pumped.hydraulic_power),
        *(pumped.volumetric_loss, pumped.mechanical_loss, zero, valve.throttling, valve.leakage),
        *(zero, zero, zero, zero),
    )


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The drive at its states ``z``, command ``u`` and spool position ``opening``: the pump
    holds p_n and delivers what the valve takes; its pressure setting stands still."""
    return on_demand(0.0, d.p_set, opening, p1_pa, p2_pa, d, xp)


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the drive stores beside the chambers, J: nothing."""
    return 0.0 * z[0]


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s``, W."""
    return 0.0 * z[0]


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """(dQ/dp the drive's paths give line A, line B, m^3/(s Pa); the fastest rate of its own
    states, 1/s) at spool ``opening``: the valve's laminar slope (stepping.stiffness_rate)."""
    slope = laminar_slope(opening, d)
    return slope, slope, 0.0 * slope
