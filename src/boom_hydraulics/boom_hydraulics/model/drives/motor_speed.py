"""How a valve drive's electric motor runs: at constant speed, stopping when idle, or at the speed the valves need.

The parameter ``motor_strategy`` (DriveConstants.motor_strategy, the index in
:data:`STRATEGIES`) picks one for the valve drives (pressure_compensated, fixed_pump,
load_sensing):

- ``constant``: the motor turns the pump at w_n = ``pump_speed_rad_s`` all the time (today's);
- ``idle_stop``: it stops after ``motor_idle_stop_s`` without valve demand and restarts on
  demand; a demand memory m (the drive's third state) jumps back to 1 while the spool is open
  and runs down linearly to 0 over T_idle without demand (eq. D60, D61);
- ``speed_on_demand``: its speed follows the speed the valves need (the drive says which),
  between w_min = ``motor_min_speed_rad_s`` and w_n (eq. D62).

Under either of the last two the motor's speed w is the drive's second state, which follows
its target with the motor's time constant tau_m (``motor_time_constant_s``); the rotors'
inertia J = ``motor_rotor_inertia_kg_m2`` then asks the torque J w' of the motor beside the
pump's, and stores J w^2 / 2 (eq. D63, D64). Under ``constant`` both states stand still and
the motor's speed is w_n, as before.

Equations and conventions: docs/model.md, section "Motor strategies".
"""

from __future__ import annotations

from typing import Any, NamedTuple

from ...jit import jitable
from ..hydraulics import larger, pos, smaller, smoothstep
from ..parameters import describe
from .constants import DriveConstants

Num = Any  # float or numpy.ndarray

#: The strategies, by the name ``motor_strategy`` gives them, in the order of their index.
STRATEGIES = ("constant", "idle_stop", "speed_on_demand")
assert describe("motor_strategy")["choices"] == STRATEGIES, "parameters' motor_strategy choices must be these"
#: The states a valve drive keeps for its motor (beside its first): the speed and idle_stop's demand memory.
STATE_NAMES = ("motor_speed", "demand_memory")
STATE_SCALES = ("angular_velocity", "unit")
STATE_UNITS = ("rad/s", "1")
#: Spool opening (either way) at which the valves demand flow: idle_stop's demand w_d rises
#: smoothly from 0 at neutral to 1 here (eq. D60).
DEMAND_OPENING = 0.02
#: The demand memory below which the motor's target falls to 0 (eq. D61): idle_stop stops the
#: motor when m has run down to this, (1 - M_STOP) T_idle after the last demand.
M_STOP = 0.01
#: Time constant with which the demand memory jumps back to 1 on demand, s (eq. D60).
MEMORY_RESET_S = 0.01


class Motor(NamedTuple):
    """The valve drive's motor at one instant (SI)."""

    speed: Num  # w, rad/s
    speed_rate: Num  # dw/dt: the rate of the drive's second state, rad/s^2 (eq. D63)
    memory_rate: Num  # dm/dt: the rate of its third state, 1/s (eq. D60)
    torque: Num  # J dw/dt: the torque the rotors' acceleration asks beside the pump's, N m (eq. D64)
    rotor_power: Num  # J w dw/dt: the rate of the rotors' kinetic energy, W (eq. D64)


@jitable
def flags(d: DriveConstants) -> tuple[Num, Num, Num]:
    """(constant, idle_stop, speed_on_demand): 1.0 for the set's strategy, 0.0 for the others."""
    return 1.0 * (d.motor_strategy == 0.0), 1.0 * (d.motor_strategy == 1.0), 1.0 * (d.motor_strategy == 2.0)


@jitable
def initial_state(d: DriveConstants) -> tuple[Num, Num]:
    """(w, m) at the start: at rest with a closed spool, idle_stop's motor has just had demand
    (it runs at w_n, as the constant motor does) and speed_on_demand's runs at w_min; the
    constant strategy keeps both states at 0 (they stand still)."""
    _, idle, on_demand = flags(d)
    return idle * d.speed + on_demand * d.min_speed, idle * 1.0


@jitable
def demand(opening: Num) -> Num:
    """w_d = smoothstep(|x| / x_d): how far the valves demand flow, 0 to 1 (eq. D60)."""
    return smoothstep(abs(opening) / DEMAND_OPENING)  # eq. D60


@jitable
def memory_rate(m: Num, opening: Num, d: DriveConstants) -> Num:
    """m' = w_d (1 - m) / tau_r - (1 - w_d) min(m / M_STOP, 1) / T_idle (eq. D60): back to 1 on
    demand within tau_r, down by 1 / T_idle without it, slowing to a stop at 0 below M_STOP."""
    w = demand(opening)
    return w * (1.0 - m) / MEMORY_RESET_S - (1.0 - w) * smaller(pos(m) / M_STOP, 1.0) / d.idle_stop_s  # eq. D60


@jitable
def running(m: Num) -> Num:
    """Whether idle_stop's motor runs: smoothstep(m / M_STOP), 1 until the memory has run down (eq. D61)."""
    return smoothstep(m / M_STOP)  # eq. D61


@jitable
def target_speed_rad_s(z: tuple, required_rad_s: Num, d: DriveConstants) -> Num:
    """The speed the motor heads for, rad/s: w_n (constant), w_n while running (idle_stop, eq. D61),
    the valves' ``required_rad_s`` between w_min and w_n (speed_on_demand, eq. D62)."""
    constant, idle, on_demand = flags(d)
    needed = larger(smaller(required_rad_s, d.speed), d.min_speed)  # eq. D62
    return constant * d.speed + idle * d.speed * running(z[2]) + on_demand * needed


@jitable
def motor(z: tuple, opening: Num, required_rad_s: Num, d: DriveConstants) -> Motor:
    """The motor at the drive's states ``z`` (z[1] its speed, z[2] idle_stop's memory) and spool
    ``opening``, ``required_rad_s`` the speed the valves need (speed_on_demand): its speed, its
    states' rates, and its rotors' torque and power (eq. D60-D64). Under ``constant`` it turns at
    w_n exactly and both rates are 0."""
    constant, idle, _ = flags(d)
    variable = 1.0 - constant
    target = target_speed_rad_s(z, required_rad_s, d)
    # eq. D63: w' = (w* - w) / tau_m; without a lag (tau_m = 0) the speed is the target at once
    rate = variable * d.motor_inv_tau * (target - z[1])
    speed = constant * d.speed + variable * (d.motor_lag * z[1] + (1.0 - d.motor_lag) * target)
    torque = d.rotor_inertia * rate  # eq. D64 (0 without a lag: the rate is 0)
    return Motor(speed, rate, idle * memory_rate(z[2], opening, d), torque, torque * speed)


@jitable
def energy(z: tuple, d: DriveConstants) -> Num:
    """J w^2 / 2: the rotors' kinetic energy, J (0 under ``constant``, whose speed state stands at 0,
    and without a lag) (eq. D64)."""
    return 0.5 * d.rotor_inertia * d.motor_lag * z[1] * z[1]


@jitable
def energy_rate(z: tuple, speed_rate: Num, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the speed's rate, W."""
    return d.rotor_inertia * d.motor_lag * z[1] * speed_rate


@jitable
def fastest_rate(d: DriveConstants) -> Num:
    """The fastest rate of the motor's states, 1/s: the speed's lag, and idle_stop's memory reset."""
    constant, idle, _ = flags(d)
    return (1.0 - constant) * d.motor_inv_tau + idle / MEMORY_RESET_S
