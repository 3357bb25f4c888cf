"""electro_mechanical: an electro-mechanical actuator (EMA), a motor, a gearing and a ball screw in place of the oil.

No valve and no oil: the command u in [-1, 1] sets the speed u w_max of a speed-controlled
motor with a torque limit (eq. D34), which turns the screw through a gearing of ratio N; the
nut advances r = l / (2 pi N) per motor radian (eq. D30) and pushes the rod through the
compliance of screw, nut, bearing and mounts (eq. D31). The gearing and screw lose
differently driven forward (eta_f) and back-driven (eta_b), through standstill by a
bristle state that also gives them, and the brake, their static friction (eq. D32): a
self-locking screw (eta_b <= 0) holds its load at rest. Below a command threshold a
spring-applied brake engages on the motor's shaft and the motor's torque fades out, so
holding costs no current (eq. D35). Lowering, the load drives the motor, which generates
back into the battery what the screw's and the motor's losses leave (eq. D33, D5).

The cylinder's two chambers are the actuator's housing, vented at tank pressure: the drive
passes the flows their volumes ask for, so they keep the tank pressure they start at
(physical.initial_state asks drives.holds_oil), and push the rod only as a hydraulic
drive's chambers at tank pressure do (the ambient's (p_amb - p_t)(S1 - S2)) (eq. D36).

States: the screw's spring force F_k = k_s (x_nut - q1) (N), the motor's speed w (rad/s)
and the bristle s (-1..1) of the gearing's, screw's and brake's friction.

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..hydraulics import smoothstep
from .constants import DriveConstants, Supply

Num = Any  # float or numpy.ndarray

#: What a plot's legend calls the drive (analysis/labels.py).
LABEL = "EMA (ball screw)"
#: The drive's states: the screw's spring force F_k (N, held to the model's pressure scale:
#: its tolerance is a fraction of a newton), the motor's speed w (rad/s) and the friction's
#: bristle s (-1..1).
STATE_NAMES = ("screw_force", "motor_speed", "friction_state")
STATE_SCALES = ("pressure", "angular_velocity", "unit")
STATE_UNITS = ("N", "rad/s", "1")
#: The drive feeds the cylinder without the 4/3 valve.
VALVE = False
#: Whether the supply holds its pressure whatever the load, its states standing still (a linear
#: model leaves them out: analysis/operating_point).
STEADY_SUPPLY = False
#: Whether the cylinder holds oil: no, its chambers are the housing, at tank pressure.
CYLINDER_OIL = False
#: The motor's rotation within which the friction's bristle turns from one sliding direction to
#: the other (the presliding angle of gearing, screw and brake), rad: 0.05 rad at the motor is
#: 0.13 mm at the rod with the defaults, and keeps the bristle's relaxation |w| / this, at full
#: speed, near the seals' (3 kHz: stepping's stability bound).
PRESLIDING_RAD = 0.05
#: The bristle's damping: the friction's and the brake's torque grow by this time their slope in
#: s times s' (LuGre's sigma_1), s: it damps the rotor's presliding on them (ratio about 0.5 at
#: the brake's and the screw's holding torque with the defaults), dissipative in every state.
PRESLIDING_DAMPING_S = 3.0e-3


@jitable
def initial_state(d: DriveConstants) -> tuple[float, float, float]:
    """The screw unloaded, the motor at rest, the friction relaxed."""
    return (0.0, 0.0, 0.0)


@jitable
def rod_force_n(z: tuple, v: Num, d: DriveConstants) -> Num:
    """F = F_k + c_s (r w - v): the screw's force on the rod, extending positive, N (eq. D31)."""
    return z[0] + d.ema_damping * (d.ema_ratio * z[1] - v)


@jitable
def brake_engagement(u: Num, d: DriveConstants) -> Num:
    """b: 1 with the brake fully engaged (u = 0), 0 released (|u| >= u_b), smooth between (eq. D35)."""
    return 1.0 - smoothstep(abs(u) / d.ema_brake_threshold)


@jitable
def load_torque_n_m(force_n: Num, bristle: Num, d: DriveConstants) -> Num:
    """T_L = r F + r (m |F| s + d F |s|): the torque the gearing and screw ask of the motor's shaft
    for the rod force F, N m (eq. D32). Sliding forward (s = sign(F)) it is r F / eta_f, back-driven
    (s = -sign(F)) r F eta_b; at rest anything between, as the bristle s holds it."""
    ideal = d.ema_ratio * force_n
    mean = d.ema_friction_mean * abs(force_n) * bristle
    friction = d.ema_ratio * (mean + d.ema_friction_skew * force_n * abs(bristle))
    return ideal + friction  # eq. D32


@jitable
def motor_torque_n_m(w: Num, u: Num, d: DriveConstants, xp: ModuleType = math) -> Num:
    """T_m = (1 - b) T_max x / sqrt(1 + x^2), x = K_w (u w_max - w) / T_max: the speed controller
    with its torque limit (a smooth saturation), faded out as the brake engages, N m (eq. D34, D35)."""
    x = d.ema_speed_gain * (u * d.speed - w) / d.ema_torque_limit
    return (1.0 - brake_engagement(u, d)) * d.ema_torque_limit * x / xp.sqrt(1.0 + x * x)


@jitable
def supply(
    z: tuple, u: Num, opening: Num, q1: Num, v: Num, p1_pa: Num, p2_pa: Num, d: DriveConstants, xp: ModuleType = math
) -> Supply:
    """The EMA at its states ``z`` (F_k, w, s) and command ``u``, the rod at velocity ``v``: the
    screw's force on the rod, the rates of its states (eq. D31-D35), the breathing of the
    chambers (eq. D36), the motor's torque and speed, and its ledger terms: the gearing's,
    screw's and brake's friction and the compliance's damping as the mechanical loss, the
    rotor's kinetic and the screw's spring energy as the rotor power. No valve: ``opening``
    is only reported."""
    f_k, w, s = z[0], z[1], z[2]
    slip = d.ema_ratio * w - v  # the nut's velocity less the rod's (eq. D30)
    force = rod_force_n(z, v, d)
    load = load_torque_n_m(force, s, d)
    engaged = brake_engagement(u, d) * d.ema_brake_torque
    s_rate = (w - abs(w) * s) / PRESLIDING_RAD  # eq. D32
    # the brake, and the bristle's damping on the friction's and the brake's slope in s (eq. D35)
    damping = PRESLIDING_DAMPING_S * (d.ema_ratio * d.ema_friction_mean * abs(force) + engaged) * s_rate
    brake = engaged * s + damping
    torque = motor_torque_n_m(w, u, d, xp)
    w_rate = (torque - load - brake) / d.ema_inertia  # eq. D33
    f_rate = d.ema_stiffness * slip  # eq. D31
    # T w = J w w' + F_k F_k' / k_s + (T_L - r F + T_B) w + c_s slip^2 + F v, where the bristle's torque
    # (T_L - r F + b T_b s = L s, its level L >= 0) times w = theta s' + |w| s is its elastic power
    # L s theta s' and its dissipation L s^2 |w| >= 0 (LuGre), and the bristle's damping dissipates
    bristle = load - d.ema_ratio * force + engaged * s
    friction_loss = bristle * s * abs(w) + damping * w + d.ema_damping * slip * slip
    stored = d.ema_inertia * w * w_rate + f_k * f_rate / d.ema_stiffness + bristle * PRESLIDING_RAD * s_rate
    q_a = d.ema_piston_area * v  # eq. D36: the housing breathes
    q_b = -d.ema_annulus_area * v
    lines = (p1_pa - d.p_tank) * q_a + (p2_pa - d.p_tank) * q_b  # zero at tank pressure
    saturated = 1.0 * (abs(d.ema_speed_gain * (u * d.speed - w)) > d.ema_torque_limit)
    zero = 0.0 * v
    return Supply(
        *(f_rate, w_rate, s_rate, q_a, q_b, 1.0 + zero, force, opening + zero, d.p_tank + zero),
        *(saturated, lines, torque, w, zero),
        *(zero, friction_loss, zero, zero, zero),
        *(zero, lines, stored, zero),
    )


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the drive stores beside the chambers, J: the rotor's J_m w^2 / 2 and the screw's
    spring F_k^2 / (2 k_s)."""
    return 0.5 * d.ema_inertia * z[1] * z[1] + 0.5 * z[0] * z[0] / d.ema_stiffness


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the rates ``s``, W."""
    return d.ema_inertia * z[1] * s.rate2 + z[0] * s.rate / d.ema_stiffness


@jitable
def stiffness(
    z: tuple,
    u: Num,
    opening: Num,
    stiff1: Num,
    stiff2: Num,
    dt: float,
    d: DriveConstants,
    xp: ModuleType = math,
    rod_mass_kg: Num = 1e300,
) -> tuple[Num, Num, Num]:
    """(dQ/dp into line A, line B: none, the housing only breathes; the fastest rate of its own
    states): the speed controller on the rotor, the rotor against the screw's spring and the
    friction's bristle, the compliance's damping on the rotor, the bristle's relaxation at
    the speed the step may reach, and the screw's spring against ``rod_mass_kg`` (a light
    boom's root at the rod: the elastic boom's; 1e300 by default, which adds nothing)."""
    r2 = d.ema_ratio * d.ema_ratio
    level = d.ema_brake_torque + d.ema_ratio * (abs(d.ema_friction_mean) + abs(d.ema_friction_skew)) * abs(z[0])
    spring = xp.sqrt((d.ema_stiffness * r2 + level / PRESLIDING_RAD) / d.ema_inertia)
    damping = (d.ema_damping * r2 + PRESLIDING_DAMPING_S * level / PRESLIDING_RAD) / d.ema_inertia
    speed = abs(z[1]) + abs(u) * d.speed
    own = d.ema_speed_gain / d.ema_inertia + spring + damping + speed / PRESLIDING_RAD
    own = own + xp.sqrt(d.ema_stiffness / rod_mass_kg)  # the screw against a light boom at the rod
    zero = 0.0 * own
    return zero, zero, own
