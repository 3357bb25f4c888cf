"""pump_controlled: an electro-hydrostatic actuator (EHA), a variable-speed motor on a bidirectional pump.

No valve: the command u in [-1, 1] sets the motor's speed, u w_max, which the motor follows
with a lag (eq. D21). The fixed pump's ports connect straight to the two chambers, and it
moves D w less its cross-port leakage from the rod-chamber line B to the piston-chamber
line A (eq. D20). The area difference flows through two pilot-operated checks to a
low-pressure reservoir (an accumulator at p_r): each lets oil into its line freely when the
line falls below p_r, and opens both ways when the other line's pressure pilots it
(eq. D22, D23). So the low-pressure line sits at the reservoir: lifting, the pump draws the
rod chamber's oil and the make-up from the reservoir; lowering, the piston chamber's oil
drives the pump as a motor, the rod chamber takes what it needs and the rest goes to the
reservoir, and the electric machine generates back into the battery (eq. D25).

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ...jit import jitable
from ..hydraulics import larger, orifice_flow, smoothstep
from ..pump import delivered_flow_m3_s
from .constants import DriveConstants, Supply, pump_point

Num = Any  # float or numpy.ndarray

#: The drive's one state: the motor's (and pump's) speed, rad/s.
STATE_NAMES = ("motor_speed",)
STATE_SCALES = ("angular_velocity",)
STATE_UNITS = ("rad/s",)
#: The drive feeds the chambers without the 4/3 valve.
VALVE = False
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = False


class Ports(NamedTuple):
    """The flows of the EHA at one instant, m^3/s."""

    q_a: Num  # into the piston-chamber line A (pump and check A) (eq. D24)
    q_b: Num  # into the rod-chamber line B (eq. D24)
    q_pump: Num  # through the pump from B to A (eq. D20)
    q_check_a: Num  # from the reservoir into line A (negative: out to it) (eq. D23)
    q_check_b: Num  # from the reservoir into line B


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The motor at rest, rad/s."""
    return (0.0, 0.0, 0.0)


@jitable
def motor_speed_rad_s(z: Num, command: Num, d: DriveConstants) -> Num:
    """The pump's speed: the motor's state, or u w_max at once without a lag, rad/s (eq. D21)."""
    return d.motor_lag * z + (1.0 - d.motor_lag) * command * d.speed


@jitable
def pilot_openings(p1_pa: Num, p2_pa: Num, d: DriveConstants) -> tuple[Num, Num]:
    """(w_A, w_B): how far each check is piloted open by the other line's pressure above the
    reservoir's, 0 closed to 1 open (eq. D22)."""
    return (
        smoothstep((p2_pa - d.p_reservoir) / d.pilot_full),  # eq. D22: line B pilots check A
        smoothstep((p1_pa - d.p_reservoir) / d.pilot_full),  # line A pilots check B
    )


@jitable
def check_flow_m3_s(p_line_pa: Num, pilot: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """Flow from the reservoir into a line through its pilot-operated check, m^3/s (eq. D23):
    K_c f(p_r - p) (w + (1 - w) [p < p_r]), f the laminar-turbulent orifice. Into the line it
    passes freely, out of it only as far as the pilot opens it."""
    dp = d.p_reservoir - p_line_pa
    return d.k_check * orifice_flow(1.0, dp, d.transition2, xp) * (pilot + (1.0 - pilot) * (dp > 0.0))  # eq. D23


@jitable
def ports(z: Num, command: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math) -> Ports:
    """The EHA's flows into the chamber lines at chamber pressures p1 (A) and p2 (B) (eq. D20, D24)."""
    speed = motor_speed_rad_s(z, command, d)
    q_pump = delivered_flow_m3_s(d.displacement, speed, p1_pa - p2_pa, d.pump_leak)  # eq. D20
    pilot_a, pilot_b = pilot_openings(p1_pa, p2_pa, d)
    q_check_a = check_flow_m3_s(p1_pa, pilot_a, d, xp)
    q_check_b = check_flow_m3_s(p2_pa, pilot_b, d, xp)
    return Ports(q_pump + q_check_a, q_check_b - q_pump, q_pump, q_check_a, q_check_b)  # eq. D24


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The EHA at its states ``z`` (the motor's speed z[0]) and command ``u``: the motor's speed
    rate (eq. D21), the pump and the checks on the chambers' lines (eq. D20-D24), the pump at
    speed w across p1 - p2 (a motor where w (p1 - p2) < 0: lowering), the checks' throttling
    and the reservoir's power relative to tank pressure (eq. D25). No valve: ``opening`` is
    only reported."""
    flows = ports(z[0], u, p1_pa, p2_pa, d, xp)
    rate = d.motor_inv_tau * (u * d.speed - z[0])  # eq. D21
    speed = motor_speed_rad_s(z[0], u, d)
    dp = p1_pa - p2_pa
    check_loss = flows.q_check_a * (d.p_reservoir - p1_pa) + flows.q_check_b * (d.p_reservoir - p2_pa)  # eq. D25
    reservoir = (d.p_reservoir - d.p_tank) * (flows.q_check_a + flows.q_check_b)  # eq. D25
    power = (p1_pa - d.p_tank) * flows.q_a + (p2_pa - d.p_tank) * flows.q_b  # what the EHA gives the lines
    pumped = pump_point(d.displacement, speed, dp, flows.q_pump, d, xp)
    zero = 0.0 * dp
    return Supply(
        *(rate, zero, zero, flows.q_a, flows.q_b, 1.0 + zero, zero, opening + zero, larger(p1_pa, p2_pa)),
        *(zero, power, pumped.torque, speed, pumped.hydraulic_power),
        *(pumped.volumetric_loss, pumped.mechanical_loss, zero, check_loss, zero),
        *(zero, reservoir, zero, zero),
    )


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the drive stores beside the chambers, J: nothing (the rotor's inertia is in its lag)."""
    return 0.0 * z[0]


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s``, W."""
    return 0.0 * z[0]


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """(dQ/dp into line A, line B; the fastest rate of its own state): a line against its check
    (its laminar slope K_c / sqrt(p_tr)) and the pump's cross-port leakage, and the motor's lag."""
    check = d.k_check * d.k_laminar / d.k_valve + d.pump_leak
    return check, check, d.motor_inv_tau + 0.0 * check
