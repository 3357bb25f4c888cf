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

As built (docs/model.md, "The EHA as built"; each off by default): the motor's speed a state
under a torque-limited speed loop on the rotors' inertia (model/drives/eha_motor.py, eq.
D50-D52), a load-holding seat valve between the pump and the piston chamber that seals the
chamber at a zero command (with the lag, once the motor has stopped) (eq. D53-D55). Its
inverter's standby is every drive's (ledger.electric_chain).

Equations and conventions: docs/model.md, sections "Drives" and "The EHA as built".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ...jit import jitable
from ..hydraulics import larger, orifice_flow, smoothstep
from ..pump import delivered_flow_m3_s
from . import eha_motor
from .constants import DriveConstants, Supply, pump_point

Num = Any  # float or numpy.ndarray

#: What a plot's legend calls the drive (analysis/labels.py).
LABEL = "EHA (pump controlled)"
#: The drive's states: the motor's (and pump's) speed, rad/s, and the integral of its speed
#: loop, rad/s (with the torque limit on, eq. D52; else it stays 0).
STATE_NAMES = ("motor_speed", "speed_loop_integral")
STATE_SCALES = ("angular_velocity", "angular_velocity")
STATE_UNITS = ("rad/s", "rad/s")
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
    dp_pump: Num  # the pump's pressure rise, its port A's pressure less p2, Pa (p1 - p2 without the holding valve)
    valve_drop: Num  # across the open load-holding valve, pump side less p1, Pa (eq. D54)
    q_seat: Num  # seat leakage of the closed load-holding valve from line A to line B (eq. D55)


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The motor at rest, rad/s."""
    return (0.0, 0.0, 0.0)


@jitable
def motor_speed_rad_s(z: Num, command: Num, d: DriveConstants) -> Num:
    """The pump's speed: the motor's state, or u w_max at once without a lag, rad/s (eq. D21)."""
    return d.motor_lag * z + (1.0 - d.motor_lag) * command * d.speed


@jitable
def pump_speed_rad_s(z: Num, command: Num, d: DriveConstants) -> Num:
    """The pump's speed: the motor's state with the torque-limited loop (eq. D51), else as
    :func:`motor_speed_rad_s` (eq. D21), rad/s."""
    return d.eha_torque_model * z + (1.0 - d.eha_torque_model) * motor_speed_rad_s(z, command, d)


@jitable
def holding_opening(speed_rad_s: Num, command: Num, d: DriveConstants) -> Num:
    """How far the load-holding valve is open, 0 closed to 1 open: fully while the motor is
    commanded at u_h of its top speed or more; at a zero command it closes, with the lag's
    speed source once the motor has stopped (eq. D53). With the torque-limited motor the
    closed valve stops the rotors itself, within milliseconds (the pump's port against its
    leakage). 1 without the valve."""
    lag = 1.0 - d.eha_torque_model
    share = larger(abs(command), lag * abs(speed_rad_s) / d.speed)
    return d.eha_holding * smoothstep(share / d.eha_holding_command) + (1.0 - d.eha_holding)  # eq. D53


@jitable
def holding_drop_pa(flow_at_p1: Num, opening: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """x: the pump side's pressure less p1 where the pump, whose flow would be ``flow_at_p1``
    at its port's pressure p1, feeds the chamber through the load-holding valve's orifice
    K_h = w_h K_c alone (eq. D54): G_p x + K_h sign(x) sqrt|x| = Q0 solved for x; 0 without
    the valve."""
    k_h = opening * d.k_check
    size = abs(flow_at_p1)
    root = 2.0 * size / (k_h + xp.sqrt(k_h * k_h + 4.0 * d.pump_leak * size) + 1e-300)  # sqrt|x|, eq. D54
    return d.eha_holding * root * root * (1.0 * (flow_at_p1 > 0.0) - 1.0 * (flow_at_p1 < 0.0))


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
    """The EHA's flows into the chamber lines at chamber pressures p1 (A) and p2 (B) (eq. D20,
    D24), through the load-holding valve where there is one (eq. D53-D55)."""
    speed = pump_speed_rad_s(z, command, d)
    opening = holding_opening(speed, command, d)
    drop = holding_drop_pa(delivered_flow_m3_s(d.displacement, speed, p1_pa - p2_pa, d.pump_leak), opening, d, xp)
    dp_pump = p1_pa - p2_pa + drop
    q_pump = delivered_flow_m3_s(d.displacement, speed, dp_pump, d.pump_leak)  # eq. D20, D54
    q_seat = d.eha_holding * (1.0 - opening) * d.seat_leak * (p1_pa - p2_pa)  # eq. D55
    pilot_a, pilot_b = pilot_openings(p1_pa, p2_pa, d)
    q_check_a = check_flow_m3_s(p1_pa, pilot_a, d, xp)
    q_check_b = check_flow_m3_s(p2_pa, pilot_b, d, xp)
    return Ports(
        q_pump + q_check_a - q_seat, q_check_b - q_pump + q_seat, q_pump, q_check_a, q_check_b, dp_pump, drop, q_seat
    )  # eq. D24, D55


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The EHA at its states ``z`` (the motor's speed z[0], its speed loop's integral z[1]) and
    command ``u``: the motor's rates (the lag, eq. D21, or the speed loop on the rotors, eq.
    D50-D52), the pump, the load-holding valve and the checks on the chambers' lines (eq.
    D20-D24, D53-D55), the pump at speed w across its pressure rise (a motor where it is
    negative: lowering), the checks' and valve's throttling, the valve's seat leakage, the
    reservoir's power relative to tank pressure (eq. D25).
    No 4/3 valve: ``opening`` is only reported."""
    flows = ports(z[0], u, p1_pa, p2_pa, d, xp)
    speed = pump_speed_rad_s(z[0], u, d)
    check_loss = flows.q_check_a * (d.p_reservoir - p1_pa) + flows.q_check_b * (d.p_reservoir - p2_pa)  # eq. D25
    valve_loss = check_loss + flows.valve_drop * flows.q_pump  # eq. D54: the holding valve's throttling
    leakage = flows.q_seat * (p1_pa - p2_pa)  # eq. D55
    reservoir = (d.p_reservoir - d.p_tank) * (flows.q_check_a + flows.q_check_b)  # eq. D25
    power = (p1_pa - d.p_tank) * flows.q_a + (p2_pa - d.p_tank) * flows.q_b  # what the EHA gives the lines
    pumped = pump_point(d.displacement, speed, flows.dp_pump, flows.q_pump, d, xp)
    m = eha_motor.motor(z[0], z[1], u, pumped.torque, d)  # eq. D50-D52
    f = d.eha_torque_model
    rate = f * m.speed_rate + (1.0 - f) * d.motor_inv_tau * (u * d.speed - z[0])  # eq. D51 or D21
    torque = f * m.torque + (1.0 - f) * pumped.torque  # the motor's: electromagnetic, or the pump's (eq. D2)
    zero = 0.0 * p1_pa
    return Supply(
        *(rate, f * m.integral_rate, zero, flows.q_a, flows.q_b, 1.0 + zero, zero, opening + zero),
        *(larger(p1_pa, p2_pa), zero, power, torque, speed, pumped.hydraulic_power),
        *(pumped.volumetric_loss, pumped.mechanical_loss, zero, valve_loss, leakage),
        *(zero, reservoir, f * m.rotor_power, zero),
    )


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the drive stores beside the chambers, J: the rotors' kinetic energy J w^2 / 2 with
    the speed loop on (with the lag, its inertia is in the lag: nothing)."""
    return 0.5 * d.eha_inertia * z[0] * z[0]


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s``, W: J w w'."""
    return d.eha_inertia * z[0] * s.rate


@jitable
def stiffness(
    z: tuple, u: Num, opening: Num, stiff1: Num, stiff2: Num, dt: float, d: DriveConstants, xp: ModuleType = math
) -> tuple[Num, Num, Num]:
    """(dQ/dp into line A, line B; the fastest rate of its own states): a line against its check
    (its laminar slope K_c / sqrt(p_tr)) and the pump's cross-port leakage (the holding valve
    only lowers it), and the motor's lag or its speed loop on the rotors (eq. D50-D52)."""
    check = d.k_check * d.k_laminar / d.k_valve + d.pump_leak
    f = d.eha_torque_model
    own = (1.0 - f) * d.motor_inv_tau + f * eha_motor.fastest_rate_1_s(stiff1, stiff2, d, xp)
    return check, check, own + 0.0 * check
