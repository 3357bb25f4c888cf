"""Paper mode: the Fig. 7 Mathematica listing of the paper, quirks included.

State y = [q1 (m), v (m/s), p1 (Pa), E_supply (J), E_loss (J)]; the energies are extra
integrals that do not feed back into q1, v, p1. As in the listing: only the piston
chamber (p2 dropped), constant V1, constant friction F_mp whatever the direction, the
spring c * q1 on the absolute cylinder length, the turbulent orifice of eq. 14, and the
acceleration of eq. 16 with its factor 1/2. A valve opening u in [0, 1] scales the
orifice area (u = 1 is the paper's case). Pressures are relative to the drain (p_37 = 0).

Equations and conventions: docs/model.md, sections "Mechanics (paper mode) and Orifices".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import jitable
from .friction import paper_friction_n
from .geometry import boom_angle_rad, lever_rad_per_m, piston_area_m2, rod_boom_angle_rad
from .hydraulics import chamber_pressure_rate, orifice_coefficient, pos, turbulent_orifice_flow
from .mechanics import boom_inertia_kgm2, paper_acceleration, paper_load_force_n
from .outputs import by_name
from .parameters import Parameters

Num = Any  # float or numpy.ndarray

STATE_NAMES = ("q1", "v", "p1", "supply_energy", "valve_loss_energy")
STATE_SCALES = ("length", "velocity", "pressure", "energy", "energy")
#: The listing conserves no energy (its eq. 16 carries a factor 1/2): no balance to check.
ENERGY_STATES = None
#: The listing steps at the user's step: no substeps from a stability bound.
STABILITY_BOUND = False


class Constants(NamedTuple):
    """Values derived once from :class:`Parameters` (floats, or arrays for a batch)."""

    a: Num
    b: Num
    h: Num
    inertia: Num  # J_1 = m1 L1^2 / 3 + mb L1^2 (eq. 8)
    weight_coeff: Num  # (0.5 m1 + mb) g L1
    boom_mass: Num
    payload_mass: Num
    boom_length: Num
    g: Num
    s1: Num
    v1: Num
    bulk_modulus: Num
    k_orifice: Num  # mu fdr sqrt(2/rho) (eq. 14, 17)
    p_n: Num
    coulomb: Num
    viscous: Num
    spring: Num
    f_external: Num  # F_ext, N, positive extending: beside p S1 in eq. 16


def constants(p: Parameters) -> Constants:
    """Derived constants of one parameter set."""
    return Constants(
        a=p.a_m,
        b=p.b_m,
        h=p.support_height_m,
        inertia=boom_inertia_kgm2(p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m),
        weight_coeff=(0.5 * p.boom_mass_kg + p.payload_mass_kg) * p.gravity_m_s2 * p.boom_length_m,
        boom_mass=p.boom_mass_kg,
        payload_mass=p.payload_mass_kg,
        boom_length=p.boom_length_m,
        g=p.gravity_m_s2,
        s1=piston_area_m2(p.piston_diameter_m),
        v1=p.piston_dead_volume_m3,
        bulk_modulus=p.bulk_modulus_pa,
        k_orifice=orifice_coefficient(
            p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3
        ),  # eq. 17
        p_n=p.supply_pressure_pa,
        coulomb=p.coulomb_friction_n,
        viscous=p.viscous_friction_n_s_m,
        spring=p.spring_stiffness_n_m,
        f_external=p.external_rod_force_n,
    )


def initial_pressure_pa(p: Parameters, q1_m: float) -> float:
    """p0 of the listing: g L1 cos(alpha0) / (a sin(phi0) S1) (0.5 m1 + mb), Pa, less
    F_ext / S1 where an external rod force carries part of the boom (eq. 16)."""
    alpha0 = boom_angle_rad(q1_m, p.a_m, p.b_m, p.support_height_m)
    phi0 = rod_boom_angle_rad(q1_m, p.a_m, p.b_m)
    s1 = piston_area_m2(p.piston_diameter_m)
    return (
        p.gravity_m_s2
        * p.boom_length_m
        * math.cos(alpha0)
        / (p.a_m * math.sin(phi0) * s1)
        * (0.5 * p.boom_mass_kg + p.payload_mass_kg)
    ) - p.external_rod_force_n / s1


@jitable
def with_payload(c: Constants, share: Num) -> Constants:
    """``c``: paper mode takes no payload schedule (the parameters refuse one)."""
    return c


def initial_state(p: Parameters, q1_m: float | None = None) -> list[float]:
    """q0, v0 and the listing's static pressure p0."""
    q1 = p.initial_length_m if q1_m is None else q1_m
    return [q1, p.initial_velocity_m_s, initial_pressure_pa(p, q1), 0.0, 0.0]


class Terms(NamedTuple):
    """The intermediate quantities of one evaluation of the listing (SI)."""

    opening: Num  # valve opening, 0..1 (pump to piston chamber only)
    flow: Num  # flow into the piston chamber, m^3/s (eq. 14)
    dp1: Num  # piston-chamber pressure rate, Pa/s (eq. 12)
    acc: Num  # rod acceleration, m/s^2 (eq. 16 as in Fig. 7)
    power: Num  # p_n Q, W
    loss: Num  # (p_n - p1) Q, W


@jitable(inline="always")
def _terms(y: list, c: Constants, u: Num, xp: ModuleType) -> Terms:
    q1, v, p1 = y[0], y[1], y[2]
    u_open = pos(u)  # the paper's valve connects pump to piston chamber only
    flow = turbulent_orifice_flow(c.k_orifice * u_open, c.p_n - p1, xp)  # eq. 14
    dp1 = chamber_pressure_rate(c.bulk_modulus, c.v1, flow, c.s1 * v)  # eq. 12, constant V1
    acc = paper_acceleration(
        q1,
        v,
        p1 * c.s1 + c.f_external,  # eq. 16: F_ext acts beside the piston force p S1
        paper_friction_n(v, c.coulomb, c.viscous),
        c.spring,
        c.inertia,
        c.weight_coeff,
        c.a,
        c.b,
        c.h,
        xp,
    )  # eq. 16 as in Fig. 7
    return Terms(u_open, flow, dp1, acc, c.p_n * flow, (c.p_n - p1) * flow)


@jitable
def derivative(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """dy/dt of the listing for valve opening ``u`` (a tuple: compiled, it stays on the stack)."""
    terms = _terms(y, c, u, xp)
    return (y[1], terms.acc, terms.dp1, terms.power, terms.loss)


@jitable
def energy(y: list, c: Constants, xp: ModuleType = math) -> Num:
    """Paper mode checks no energy balance (see ENERGY_STATES)."""
    return 0.0 * y[0]


@jitable
def stiffness_rate(y: list, c: Constants, u: Num, dt: float, xp: ModuleType = math) -> Num:
    """Paper mode steps as the listing does, at the user's step: no stability bound (see STABILITY_BOUND)."""
    return 0.0 * y[0]


@jitable
def outputs(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """Outputs of DriveState at state ``y`` as a tuple in the order of model.outputs.OUTPUT_NAMES
    (flags 1.0 or 0.0); rod-side quantities are 0 (not modelled)."""
    terms = _terms(y, c, u, xp)
    q1, v, acc = y[0], y[1], terms.acc
    zero = 0.0 * q1
    return (
        t,  # t
        q1,  # q1
        v,  # v
        acc,  # a
        boom_angle_rad(q1, c.a, c.b, c.h, xp),  # alpha
        lever_rad_per_m(q1, c.a, c.b, xp) * v,  # alpha_rate
        y[2],  # p1
        zero,  # p2
        terms.flow,  # q_in1
        zero,  # q_in2
        y[2] * c.s1,  # f_hyd
        paper_load_force_n(
            q1, v, acc, c.inertia, c.boom_mass, c.payload_mass, c.boom_length, c.g, c.a, c.b, xp
        ),  # f_load, eq. 10
        paper_friction_n(v, c.coulomb, c.viscous),  # f_friction
        u,  # u
        terms.opening,  # x_v
        c.p_n + zero,  # p_supply
        terms.power,  # power
        y[3],  # supply_energy
        y[4],  # valve_loss_energy
        zero + math.nan,  # battery_power: paper mode has no battery
        zero + math.nan,  # battery_drawn
        zero + math.nan,  # battery_returned
        zero + math.nan,  # lift_work
        zero + math.nan,  # reservoir_power_j
        zero + math.nan,  # battery_loss_j
        zero + math.nan,  # motor_loss_j
        zero + math.nan,  # standby_loss_j
        zero + math.nan,  # pump_volumetric_loss_j
        zero + math.nan,  # pump_mechanical_loss_j
        zero + math.nan,  # main_relief_loss_j
        zero + math.nan,  # valve_loss_j
        zero + math.nan,  # leakage_loss_j
        zero + math.nan,  # port_relief_loss_j
        zero + math.nan,  # friction_work_j
        zero + math.nan,  # end_stop_work_j
        zero + math.nan,  # ambient_work_j
        zero + math.nan,  # external_work_j
        zero + math.nan,  # oil_work_j
        zero + math.nan,  # rotor_power_j
        zero + math.nan,  # kinetic_power_j
        zero + math.nan,  # potential_power_j
        zero + math.nan,  # accumulator_loss_j
        zero + math.nan,  # gas_power_j
        zero + math.nan,  # line_loss_j
        zero + math.nan,  # structural_loss_j
        zero,  # void1
        zero,  # void2
        zero,  # boom_deflection: a rigid boom
        zero,  # boom_deflection_rate
        zero,  # hinge_force_x: not modelled in paper mode
        zero,  # hinge_force_z
        1.0 * (zero != zero),  # at_end_stop
        1.0 * (y[2] < 0.0),  # cavitation
        1.0 * (zero != zero),  # relief_open
        1.0 * (zero != zero),  # pump_saturated
        1.0 * (zero != zero),  # battery_overloaded: paper mode has no battery
    )


@jitable
def samples(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """The outputs the run metrics take (model.outputs.SAMPLE_NAMES, in its order), as
    :func:`outputs` gives them, without computing the others (a test holds them equal)."""
    q1 = y[0]
    zero = 0.0 * q1
    return (
        t,  # t
        q1,  # q1
        y[1],  # v
        boom_angle_rad(q1, c.a, c.b, c.h, xp),  # alpha
        y[2],  # p1
        zero,  # p2
        u,  # u
        1.0 * (y[2] < 0.0),  # cavitation
        1.0 * (zero != zero),  # relief_open
        y[3],  # supply_energy
        y[4],  # valve_loss_energy
        zero + math.nan,  # battery_drawn: paper mode has no battery
        zero + math.nan,  # battery_returned
        zero + math.nan,  # lift_work
    )


def observe(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> dict[str, Num]:
    """The outputs by name (flags as booleans): :func:`outputs` through model.outputs.by_name."""
    return by_name(outputs(t, y, c, u, xp))
