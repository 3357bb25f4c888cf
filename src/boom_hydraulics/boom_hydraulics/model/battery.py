"""The battery: an open-circuit voltage U behind an internal resistance R, and its state of charge.

Signs: the current I > 0 discharges. For the power P the inverter draws at the terminals
(negative when it returns power), U I - R I^2 = P gives the current (eq. D8); the battery
gives U I (eq. D9: its chemical power, negative while charging), of which R I^2 heats it in
both directions. The state of charge falls by U I over the usable energy (eq. D10).

Equations and conventions: docs/model.md, section "Battery".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ..jit import jitable
from .hydraulics import pos

Num = Any  # float or numpy.ndarray

#: Joules in a kilowatt hour.
J_PER_KWH = 3.6e6


@jitable
def battery_current_a(power_w: Num, voltage_v: Num, resistance_ohm: Num, xp: ModuleType = math) -> Num:
    """I = 2 P / (U + sqrt(U^2 - 4 R P)), A: the root of U I - R I^2 = P nearer zero (eq. D8).

    This form holds for R = 0 (I = P / U) and loses no digits for small R. Beyond the most the
    battery can give, U^2 / (4 R) (:func:`overloaded`), there is no root: the square root's
    argument is taken as 0 (I = 2 P / U), the terminals then give less than P, and the energy
    ledger does not close while :func:`overloaded` flags it."""
    return 2.0 * power_w / (voltage_v + xp.sqrt(pos(voltage_v * voltage_v - 4.0 * resistance_ohm * power_w)))


@jitable
def battery_loss_w(current_a: Num, resistance_ohm: Num) -> Num:
    """R I^2: the heat of the internal resistance, W, charging or discharging (eq. D9)."""
    return resistance_ohm * current_a * current_a  # eq. D9


@jitable
def chemical_power_w(current_a: Num, voltage_v: Num) -> Num:
    """U I: the power the battery's store gives (negative: takes), W; terminal power plus R I^2 (eq. D9)."""
    return voltage_v * current_a  # eq. D9


@jitable
def state_of_charge_rate_1_s(current_a: Num, voltage_v: Num, capacity_j: Num) -> Num:
    """dSoC/dt = -U I / E_usable, 1/s (eq. D10)."""
    return -voltage_v * current_a / capacity_j  # eq. D10


def state_of_charge(initial: float, drawn_j: float, returned_j: float, capacity_j: float) -> float:
    """The state of charge after the battery gave ``drawn_j`` and took back ``returned_j``,
    from ``initial`` (eq. D10 integrated: the energy the battery's chemistry gave over its
    usable energy)."""
    return initial - (drawn_j - returned_j) / capacity_j


@jitable
def overloaded(power_w: Num, voltage_v: Num, resistance_ohm: Num) -> Num:
    """1.0 where ``power_w`` is beyond U^2 / (4 R), the most the battery can give (eq. D11), else 0.0."""
    return 1.0 * (4.0 * resistance_ohm * power_w > voltage_v * voltage_v)  # eq. D11
