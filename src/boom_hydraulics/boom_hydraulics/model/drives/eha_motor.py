"""The EHA's motor as built: a PI speed loop with a torque limit on the rotors' inertia.

The command u sets the speed u w_max; the inverter gives the torque the speed loop asks for,
at most T_max = min(the torque limit, k_t I_max) either way (eq. D50). The rotors (motor and
pump) of inertia J take the difference between that torque and the pump's (eq. D2, D51), so
that against a stop the motor stalls at its torque limit, where the pump holds
dp = T_max / (D (1 + c_f)). The loop's integral relaxes to what the limited torque leaves
(back-calculation), so that it does not wind up while the torque is limited (eq. D52).

Equations and conventions: docs/model.md, section "The EHA as built".
"""

from __future__ import annotations

from typing import Any, NamedTuple

from ...jit import jitable
from ..hydraulics import larger, smaller
from ..pump import FRICTION_SPEED_RAD_S
from .constants import DriveConstants

Num = Any  # float or numpy.ndarray


class Motor(NamedTuple):
    """The motor under its speed loop at one instant (SI)."""

    torque: Num  # T_m, the electromagnetic torque, N m (eq. D50)
    speed_rate: Num  # dw/dt, rad/s^2 (eq. D51)
    integral_rate: Num  # dI/dt of the speed loop's integral, rad/s^2 (eq. D52)
    rotor_power: Num  # J w dw/dt = w (T_m - T_p), W


@jitable
def torque_n_m(speed_rad_s: Num, integral_rad_s: Num, command: Num, d: DriveConstants) -> Num:
    """T_m = clamp(K_w (u w_max - w + I), -T_max, T_max), N m (eq. D50)."""
    asked = d.eha_speed_gain * (command * d.speed - speed_rad_s + integral_rad_s)
    return smaller(larger(asked, -d.eha_torque_max), d.eha_torque_max)  # eq. D50


@jitable
def motor(speed_rad_s: Num, integral_rad_s: Num, command: Num, pump_torque_n_m: Num, d: DriveConstants) -> Motor:
    """The motor at speed w with the loop's integral I under command u, the pump taking
    ``pump_torque_n_m`` (eq. D2) from its shaft (eq. D50-D52)."""
    torque = torque_n_m(speed_rad_s, integral_rad_s, command, d)
    net = torque - pump_torque_n_m
    return Motor(
        torque,
        net * d.eha_inv_inertia,  # eq. D51: J w' = T_m - T_p
        (torque / d.eha_speed_gain - integral_rad_s) * d.eha_inv_integral_time,  # eq. D52
        speed_rad_s * net,  # d/dt (J w^2 / 2)
    )


@jitable
def fastest_rate_1_s(stiff1: Num, stiff2: Num, d: DriveConstants, xp: Any) -> Num:
    """A bound on the motor's fastest rate, 1/s (stepping's stability bound): the speed loop
    (K_w / J and 1 / T_i), the rotors against the chambers' oil springs through the pump
    (sqrt(D^2 (E/V1 + E/V2) / J)), the pump's friction torque through standstill (c_f D dp /
    (w_f J), dp up to twice p_n), and the pump against a closed load-holding valve, where its
    leakage alone takes its flow (D^2 (1 + c_f) / (G_p J))."""
    inv_j = d.eha_inv_inertia
    loop = d.eha_speed_gain * inv_j + d.eha_inv_integral_time
    spring = xp.sqrt(d.displacement * d.displacement * (stiff1 + stiff2) * inv_j)
    friction = d.torque_loss * d.displacement * 2.0 * d.p_set * inv_j / FRICTION_SPEED_RAD_S
    squared = d.displacement * d.displacement
    closed = d.eha_holding * squared * (1.0 + d.torque_loss) * inv_j / larger(d.pump_leak, 1e-30)
    return loop + spring + friction + closed
