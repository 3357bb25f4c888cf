"""The electric motor with its inverter: the electrical power for a shaft torque and speed.

One loss model serves every drive and both directions. The losses are positive whatever
way the power flows, so a motoring machine draws its shaft power plus the losses, and a
generating one returns its shaft power less the losses (eq. D5, D6):

- copper, with the torque squared (the windings' and the inverter's conduction, R I^2);
- the inverter's switching, with the current, so with |T|;
- iron and friction: hysteresis and bearing friction with |w|, eddy currents with w^2,
  windage with |w|^3;
- the inverter's standby, a constant while it is enabled (the ledger books it as standby).

Each coefficient comes from the rated point (torque T_r, speed w_r, efficiency eta) and the
share of the rated loss each term takes (:func:`loss_coefficients`); the shares default to
today's two terms (copper and |w|), the others zero. At the rated point the efficiency is
eta motoring and 2 - 1/eta generating, whatever the shares.

Equations and conventions: docs/model.md, section "Electric motor and inverter".
"""

from __future__ import annotations

from typing import Any, NamedTuple

from ..jit import jitable

Num = Any  # float or numpy.ndarray


class MotorLosses(NamedTuple):
    """The coefficients of eq. D6 (SI)."""

    copper: Num  # k_c, W/(N m)^2: windings and inverter conduction
    iron: Num  # k_s, W/(rad/s): hysteresis, bearing friction
    current: Num  # k_i, W/(N m): inverter switching
    eddy: Num  # k_e, W/(rad/s)^2: eddy currents
    windage: Num  # k_w, W/(rad/s)^3: windage
    standby: Num  # P_0, W: the inverter enabled


@jitable
def loss_coefficients(
    rated_torque_n_m: float,
    rated_speed_rad_s: float,
    efficiency: float,
    copper_fraction: float,
    current_fraction: float,
    eddy_fraction: float,
    windage_fraction: float,
    standby_w: float,
) -> MotorLosses:
    """The coefficients of eq. D6 from the rated point: the rated loss L_r = T_r w_r (1 / eta - 1)
    splits into copper f_c L_r = k_c T_r^2, switching f_i L_r = k_i T_r, eddy f_e L_r = k_e w_r^2,
    windage f_w L_r = k_w w_r^3, the standby P_0 and the rest, hysteresis and friction,
    (1 - f_c - f_i - f_e - f_w - P_0 / L_r) L_r = k_s w_r (eq. D6)."""
    rated_loss = rated_torque_n_m * rated_speed_rad_s * (1.0 / efficiency - 1.0)
    speed_share = (1.0 - copper_fraction) - (current_fraction + eddy_fraction + windage_fraction)
    speed_loss = speed_share * rated_loss - standby_w
    return MotorLosses(
        copper_fraction * rated_loss / (rated_torque_n_m * rated_torque_n_m),
        speed_loss / rated_speed_rad_s,
        current_fraction * rated_loss / rated_torque_n_m,
        eddy_fraction * rated_loss / (rated_speed_rad_s * rated_speed_rad_s),
        windage_fraction * rated_loss / (rated_speed_rad_s * rated_speed_rad_s * rated_speed_rad_s),
        standby_w,
    )


@jitable
def motor_loss_w(torque_n_m: Num, speed_rad_s: Num, copper_w_n2m2: Num, iron_w_s_rad: Num) -> Num:
    """k_c T^2 + k_s |w|: the copper and the hysteresis and friction terms of eq. D6, W, the same
    in both directions (the whole loss where the other shares are zero, the defaults).

    Holding a torque at standstill costs the copper loss alone."""
    return copper_w_n2m2 * torque_n_m * torque_n_m + iron_w_s_rad * abs(speed_rad_s)  # eq. D6


@jitable
def machine_loss_w(torque_n_m: Num, speed_rad_s: Num, m: MotorLosses) -> Num:
    """P_m = k_c T^2 + k_s |w| + k_i |T| + k_e w^2 + k_w |w|^3: the motor's and inverter's losses
    that depend on the operating point, W, the same in both directions (eq. D6)."""
    w = abs(speed_rad_s)
    return (
        motor_loss_w(torque_n_m, speed_rad_s, m.copper, m.iron)
        + m.current * abs(torque_n_m)
        + m.eddy * w * w
        + m.windage * w * w * w
    )  # eq. D6


@jitable
def input_power_w(torque_n_m: Num, speed_rad_s: Num, m: MotorLosses) -> Num:
    """P_el = T w + P_m + P_0: what the enabled inverter draws from the battery (negative:
    returns to it), W (eq. D5)."""
    return torque_n_m * speed_rad_s + machine_loss_w(torque_n_m, speed_rad_s, m) + m.standby  # eq. D5


@jitable
def efficiency(torque_n_m: Num, speed_rad_s: Num, m: MotorLosses) -> Num:
    """Shaft over electrical power motoring (T w > 0), electrical over shaft power generating (eq. D7)."""
    shaft = torque_n_m * speed_rad_s
    electrical = input_power_w(torque_n_m, speed_rad_s, m)
    motoring = 1.0 * (shaft > 0.0)
    return motoring * shaft / electrical + (1.0 - motoring) * electrical / shaft
