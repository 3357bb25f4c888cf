"""The electric motor with its inverter: the electrical power for a shaft torque and speed.

One loss model serves both directions. The losses, copper (with the torque squared) and
iron and switching (with the speed), are positive whatever way the power flows, so a
motoring machine draws its shaft power plus the losses, and a generating one returns its
shaft power less the losses (eq. D5, D6). At the rated point the efficiency is eta
motoring and 2 - 1/eta generating.

Equations and conventions: docs/model.md, section "Electric motor and inverter".
"""

from __future__ import annotations

from typing import Any

from ..jit import jitable

Num = Any  # float or numpy.ndarray


@jitable
def loss_coefficients(
    rated_torque_n_m: float, rated_speed_rad_s: float, efficiency: float, copper_fraction: float
) -> tuple[float, float]:
    """(k_c, k_s) of eq. D6 from the rated point: the rated loss L_r = T_r w_r (1 / eta - 1)
    splits into copper f L_r = k_c T_r^2 and iron and switching (1 - f) L_r = k_s w_r."""
    rated_loss = rated_torque_n_m * rated_speed_rad_s * (1.0 / efficiency - 1.0)
    return (
        copper_fraction * rated_loss / (rated_torque_n_m * rated_torque_n_m),
        (1.0 - copper_fraction) * rated_loss / rated_speed_rad_s,
    )


@jitable
def motor_loss_w(torque_n_m: Num, speed_rad_s: Num, copper_w_n2m2: Num, iron_w_s_rad: Num) -> Num:
    """P_m = k_c T^2 + k_s |w|: motor and inverter losses, W, the same in both directions (eq. D6).

    Holding a torque at standstill costs the copper loss alone."""
    return copper_w_n2m2 * torque_n_m * torque_n_m + iron_w_s_rad * abs(speed_rad_s)  # eq. D6


@jitable
def electrical_power_w(torque_n_m: Num, speed_rad_s: Num, copper_w_n2m2: Num, iron_w_s_rad: Num) -> Num:
    """P_el = T w + P_m: what the inverter draws from the battery (negative: returns to it), W (eq. D5)."""
    return torque_n_m * speed_rad_s + motor_loss_w(torque_n_m, speed_rad_s, copper_w_n2m2, iron_w_s_rad)  # eq. D5
