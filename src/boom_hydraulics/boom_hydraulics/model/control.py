"""Closed-loop position control of the boom angle: a pure function of state and setpoint.

The controller turns a boom-angle setpoint (angle and rate) into a valve opening in
[-1, 1], which then goes through the same spool, valve and dynamics as a manual command.

    u = kff(q1) alpha_ref' + Kp e + I,      e = alpha_ref - alpha

- **Feedforward.** kff(q1) = 1 / (k(q1) v_full(q1)): the opening whose steady rod speed
  gives the setpoint's rate. v_full is the rod speed at full opening of a quasi-static
  meter-in/meter-out pair of equal orifices, against the static load of eq. 6 less the
  external rod force F_ext:
  lifting S1 v = K sqrt(p_s - p1), S2 v = K sqrt(p2 - p_t) with p1 S1 - p2 S2 = F give
  v_up = K sqrt((p_s S1 - p_t S2 - F) / (S1^3 + S2^3)); lowering likewise
  v_down = K sqrt((F + p_s S2 - p_t S1) / (S1^3 + S2^3)); each at most the pump's flow
  over the fed area. k = d(alpha)/dq1 is the lever of eq. 5.
- **PI with anti-windup.** The integral grows by Ki e dt only near the setpoint (|e| within
  ``INTEGRATION_ZONE_RAD``) and while the opening is not saturated in the direction the error
  pushes, and it stays within +-``INTEGRAL_LIMIT``: a large step, whose error the proportional
  term works off, leaves nothing wound up to carry the boom past its target.
- **Dead-band with hysteresis.** With a setpoint at rest, the controller closes the valve
  (u = 0, integral cleared) once |e| < deadband and opens it again only when |e| grows past
  ``HYSTERESIS`` x deadband: the load-holding valve holds the boom, and the valve never
  chatters around the target.

Functions take floats (``xp=math``) and numpy arrays (``xp=numpy``, one entry per parameter
set): only operators and functions both have.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import jitable
from .geometry import boom_angle_rad, cos_boom_angle, lever_rad_per_m
from .hydraulics import larger, smaller

Num = Any  # float or numpy.ndarray

#: The integral only grows while the angle error is within this, rad (2 degrees).
INTEGRATION_ZONE_RAD = 0.035
#: Largest opening the integral term may contribute.
INTEGRAL_LIMIT = 0.5
#: The valve opens again when the error grows past this multiple of the dead-band.
HYSTERESIS = 2.0
#: Lowest pressure margin the feedforward assumes across the valve, as a fraction of p_s.
_MIN_MARGIN = 0.05


class Gains(NamedTuple):
    """Controller settings (floats, or arrays for a batch)."""

    kp: Num  # valve opening per rad of angle error, 1/rad
    ki: Num  # valve opening per rad s of integrated error, 1/(rad s)
    deadband: Num  # angle error inside which the valve closes at a resting setpoint, rad
    lower_limit: Num  # smallest opening: -1 (physical mode)


class ControlState(NamedTuple):
    """What the controller remembers between steps."""

    integral: Num  # the integral term's opening, within +-INTEGRAL_LIMIT
    holding: Num  # 1.0 while the dead-band holds the valve closed, else 0.0


def gains_of(p: Any) -> Gains:
    """The controller settings of a Parameters set."""
    return Gains(
        kp=p.control_position_gain_1_rad,
        ki=p.control_integral_gain_1_rad_s,
        deadband=p.control_deadband_rad,
        lower_limit=0.0 if p.mode == "paper" else -1.0,
    )


def initial_control_state(like: Num = 0.0) -> ControlState:
    """No integral, not holding (``like``: a float, or an array of the batch's shape)."""
    zero = like * 0.0
    return ControlState(integral=zero, holding=zero)


@jitable
def full_opening_rate(q1_m: Num, c: Any, xp: ModuleType = math) -> tuple[Num, Num]:
    """Boom rates (rad/s) at full opening, lifting and lowering, at cylinder length ``q1_m``
    (the feedforward's plant model; ``c``: physical-mode Constants): through the valve, or, for
    a drive whose command sets its motor's speed, that drive's rod speed at full command."""
    lever = lever_rad_per_m(q1_m, c.a, c.b, xp)
    # eq. 6: F = M_g k, less the external rod force that carries part of it (eq. 11)
    force = c.weight_coeff * cos_boom_angle(q1_m, c.a, c.b, c.h, xp) * lever - c.f_external
    cubes = c.s1 * c.s1 * c.s1 + c.s2 * c.s2 * c.s2
    margin = _MIN_MARGIN * c.p_set * (c.s1 + c.s2)
    v_up = c.k_valve * xp.sqrt(larger(c.p_set * c.s1 - c.p_tank * c.s2 - force, margin) / cubes)
    v_down = c.k_valve * xp.sqrt(larger(force + c.p_set * c.s2 - c.p_tank * c.s1, margin) / cubes)
    direct = 1.0 * (c.command_rod_speed > 0.0)  # a drive without the valve: its motor sets the speed
    v_up = smaller(v_up, c.max_flow / c.s1) + direct * (c.command_rod_speed - smaller(v_up, c.max_flow / c.s1))
    v_down = smaller(v_down, c.max_flow / c.s2) + direct * (c.command_rod_speed - smaller(v_down, c.max_flow / c.s2))
    return lever * v_up, lever * v_down


@jitable
def position_command(
    g: Gains,
    s: ControlState,
    q1_m: Num,
    c: Any,
    ref_rad: Num,
    ref_rate_rad_s: Num,
    dt_s: float,
    xp: ModuleType = math,
) -> tuple[Num, ControlState]:
    """The valve opening for the next step, and the controller's state after it.

    ``q1_m``: cylinder length now; ``c``: the model's Constants; ``ref_rad`` and
    ``ref_rate_rad_s``: the setpoint's boom angle and rate; ``dt_s``: the step it holds for.
    """
    alpha = boom_angle_rad(q1_m, c.a, c.b, c.h, xp)
    error = ref_rad - alpha
    size = abs(error)
    up, down = full_opening_rate(q1_m, c, xp)
    rising = ref_rate_rad_s > 0.0
    feedforward = ref_rate_rad_s / (up * rising + down * (1.0 - rising))
    at_rest = ref_rate_rad_s == 0.0
    # hysteresis: close inside the dead-band, open again beyond HYSTERESIS times it
    band = g.deadband * (1.0 + (HYSTERESIS - 1.0) * s.holding)
    holding = 1.0 * (at_rest & (size < band))
    free = feedforward + g.kp * error + s.integral
    high_limit, low_limit = 1.0, g.lower_limit
    pushing_out = ((free >= high_limit) & (error > 0.0)) | ((free <= low_limit) & (error < 0.0))
    integrating = (1.0 - pushing_out) * (size < INTEGRATION_ZONE_RAD)
    integral = s.integral + g.ki * error * dt_s * integrating
    integral = smaller(larger(integral, -INTEGRAL_LIMIT), INTEGRAL_LIMIT) * (1.0 - holding)
    u = smaller(larger(feedforward + g.kp * error + integral, low_limit), high_limit) * (1.0 - holding)
    return u, ControlState(integral=integral, holding=holding)
