"""Physical mode: the corrected boom drive with both chambers, a 4/3 valve and end stops.

State y = [q1 (m), v (m/s), p1 (Pa), p2 (Pa), x_v (spool, -1..1), E_supply (J), E_loss (J)].
Pressures are absolute. What this mode corrects in the paper's equations is listed in the
README ("The model"): the Lagrange equation with its m'(q1) q1'^2 / 2 term, both chambers
with volumes that follow the rod, a laminar-turbulent orifice, spool lag, supply limit,
reliefs, cavitation floor, seal friction and end stops. Functions work on floats and, for
batches, on numpy arrays per state component (``xp=numpy`` and array-valued constants).

Equations and conventions: docs/model.md, sections "What physical mode corrects, and why".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from .end_stops import end_stop_force_n
from .friction import seal_friction_n
from .geometry import annulus_area_m2, boom_angle_rad, lever_rad_per_m, piston_area_m2, static_rod_force_of
from .hydraulics import (
    chamber_pressure_rate,
    hold_at_floor,
    orifice_coefficient,
    pos,
    relief_flow,
    supply_pressure,
    valve_flows,
)
from .mechanics import boom_inertia_kgm2, load_force_n, rod_acceleration
from .parameters import Parameters

Num = Any  # float or numpy.ndarray

STATE_NAMES = ("q1", "v", "p1", "p2", "x_v", "supply_energy", "valve_loss_energy")
STATE_SCALES = ("length", "velocity", "pressure", "pressure", "unit", "energy", "energy")


class Constants(NamedTuple):
    """Values derived once from :class:`Parameters` (floats, or arrays for a batch)."""

    a: Num
    b: Num
    h: Num
    inertia: Num  # J_c1, kg m^2 (eq. 8)
    weight_coeff: Num  # (m1/2 + mb) L1 g, N m
    s1: Num  # piston area, m^2
    s2: Num  # annulus area, m^2
    q_min: Num
    q_max: Num
    v1_dead: Num
    v2_dead: Num
    bulk_modulus: Num
    p_cav: Num
    k_valve: Num  # mu f_max sqrt(2/rho) (eq. 14, 17)
    transition2: Num  # p_tr^2, Pa^2
    leak: Num
    lag: Num  # 1.0 with a spool lag, 0.0 without
    inv_tau: Num  # 1 / spool time constant (0 without lag)
    p_supply: Num
    p_tank: Num
    pump_max_flow: Num
    p_relief: Num
    g_relief: Num
    coulomb: Num
    static: Num
    stribeck: Num
    smoothing: Num
    viscous: Num
    spring: Num
    spring_free: Num
    stop_k: Num
    stop_c: Num


def constants(p: Parameters) -> Constants:
    """Derived constants of one parameter set."""
    lag = 1.0 if p.spool_time_constant_s > 0.0 else 0.0
    return Constants(
        a=p.a_m,
        b=p.b_m,
        h=p.support_height_m,
        inertia=boom_inertia_kgm2(p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m),
        weight_coeff=(0.5 * p.boom_mass_kg + p.payload_mass_kg) * p.boom_length_m * p.gravity_m_s2,
        s1=piston_area_m2(p.piston_diameter_m),
        s2=annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m),
        q_min=p.cylinder_min_length_m,
        q_max=p.cylinder_max_length_m,
        v1_dead=p.piston_dead_volume_m3,
        v2_dead=p.rod_dead_volume_m3,
        bulk_modulus=p.bulk_modulus_pa,
        p_cav=p.cavitation_pressure_pa,
        k_valve=orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3),
        transition2=p.transition_pressure_pa**2,
        leak=p.valve_leakage_m3_s_pa,
        lag=lag,
        inv_tau=lag / p.spool_time_constant_s if lag else 0.0,
        p_supply=p.supply_pressure_pa,
        p_tank=p.tank_pressure_pa,
        pump_max_flow=p.pump_max_flow_m3_s,
        p_relief=p.relief_pressure_pa,
        g_relief=p.relief_rated_flow_m3_s / p.relief_range_pa,
        coulomb=p.coulomb_friction_n,
        static=p.static_friction_n,
        stribeck=p.stribeck_velocity_m_s,
        smoothing=p.friction_smoothing_velocity_m_s,
        viscous=p.viscous_friction_n_s_m,
        spring=p.spring_stiffness_n_m,
        spring_free=p.spring_free_length_m,
        stop_k=p.end_stop_stiffness_n_m,
        stop_c=p.end_stop_damping_n_s_m,
    )


def initial_state(p: Parameters, q1_m: float | None = None) -> list[float]:
    """Rod at rest at ``q1_m`` (default q1(0)), valve closed, rod chamber at tank pressure,
    piston chamber at the pressure that holds the boom statically (eq. 6)."""
    q1 = p.initial_length_m if q1_m is None else q1_m
    force = static_rod_force_of(p, q1)
    s1 = piston_area_m2(p.piston_diameter_m)
    s2 = annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    spring = p.spring_stiffness_n_m * (q1 - p.spring_free_length_m)
    p2 = p.tank_pressure_pa
    p1 = (force + spring + p2 * s2) / s1
    return [q1, p.initial_velocity_m_s, p1, p2, 0.0, 0.0, 0.0]


class Terms(NamedTuple):
    """The intermediate quantities of one evaluation, shared by derivative and observe (SI)."""

    spool: Num  # spool position seen by the flow paths, -1..1
    p_supply: Num  # supply pressure after the pump's flow limit, Pa
    q_in1: Num  # net flow into the piston chamber, m^3/s (eq. 12)
    q_in2: Num  # net flow into the rod chamber, m^3/s (eq. 13)
    q_relief1: Num  # port relief flows to tank, m^3/s
    q_relief2: Num
    dp1: Num  # chamber pressure rates, Pa/s (eq. 12, 13)
    dp2: Num
    f_hyd: Num  # p1 S1 - p2 S2, N
    f_stop: Num  # end-stop force, N
    f_friction: Num  # seal friction, N (opposes the motion)
    acc: Num  # rod acceleration, m/s^2 (eq. 11)
    power: Num  # power drawn from the supply, W
    loss: Num  # power dissipated in the valve and the relief valves, W


def _terms(y: list, c: Constants, u: Num, xp: ModuleType) -> Terms:
    """Every intermediate quantity of one evaluation, shared by derivative and observe."""
    q1, v, p1, p2, x_v = y[0], y[1], y[2], y[3], y[4]
    x = c.lag * x_v + (1.0 - c.lag) * u  # spool position seen by the flow paths
    ps = supply_pressure(x, c.p_supply, p1, p2, c.k_valve, c.transition2, c.pump_max_flow, xp)
    q_pa, q_at, q_pb, q_bt = valve_flows(x, ps, c.p_tank, p1, p2, c.k_valve, c.transition2, c.leak, xp)
    q_r1 = relief_flow(p1, c.p_relief, c.g_relief)
    q_r2 = relief_flow(p2, c.p_relief, c.g_relief)
    q_in1 = q_pa - q_at - q_r1  # Q_1 into the piston chamber
    q_in2 = q_pb - q_bt - q_r2  # -Q_2 of eq. 13: into the rod chamber
    vol1 = c.v1_dead + c.s1 * (q1 - c.q_min)  # dead + swept volume
    vol2 = c.v2_dead + c.s2 * (c.q_max - q1)
    dp1 = hold_at_floor(p1, chamber_pressure_rate(c.bulk_modulus, vol1, q_in1, c.s1 * v), c.p_cav)  # eq. 12
    dp2 = hold_at_floor(p2, chamber_pressure_rate(c.bulk_modulus, vol2, q_in2, -c.s2 * v), c.p_cav)  # eq. 13
    f_hyd = p1 * c.s1 - p2 * c.s2
    f_stop = end_stop_force_n(q1, v, c.q_min, c.q_max, c.stop_k, c.stop_c)
    f_friction = seal_friction_n(v, c.coulomb, c.static, c.stribeck, c.smoothing, c.viscous, xp)
    f_rod = f_hyd - f_friction - c.spring * (q1 - c.spring_free) + f_stop  # eq. 11 without the boom load
    acc = rod_acceleration(q1, v, f_rod, c.inertia, c.weight_coeff, c.a, c.b, c.h, xp)
    power = (ps - c.p_tank) * (q_pa + q_pb)
    loss = (
        q_pa * (ps - p1)
        + q_at * (p1 - c.p_tank)
        + q_pb * (ps - p2)
        + q_bt * (p2 - c.p_tank)
        + q_r1 * (p1 - c.p_tank)
        + q_r2 * (p2 - c.p_tank)
    )
    return Terms(x, ps, q_in1, q_in2, q_r1, q_r2, dp1, dp2, f_hyd, f_stop, f_friction, acc, power, loss)


def derivative(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> list:
    """dy/dt of the physical model for valve command ``u`` (held over the step)."""
    terms = _terms(y, c, u, xp)
    return [y[1], terms.acc, terms.dp1, terms.dp2, c.inv_tau * (u - y[4]), terms.power, terms.loss]


def project(y: list, c: Constants) -> list:
    """Keep chamber pressures at or above the cavitation floor after a step."""
    y[2] = c.p_cav + pos(y[2] - c.p_cav)
    y[3] = c.p_cav + pos(y[3] - c.p_cav)
    return y


def observe(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> dict[str, Num]:
    """Every output of DriveState at state ``y`` (SI units; see DriveOutputs)."""
    terms = _terms(y, c, u, xp)
    q1, v, acc = y[0], y[1], terms.acc
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    floor_margin = c.p_cav * 1e-9 + 1e-6
    return {
        "t": t,
        "q1": q1,
        "v": v,
        "a": acc,
        "alpha": boom_angle_rad(q1, c.a, c.b, c.h, xp),
        "alpha_rate": k * v,
        "p1": y[2],
        "p2": y[3],
        "q_in1": terms.q_in1,
        "q_in2": terms.q_in2,
        "f_hyd": terms.f_hyd,
        "f_load": load_force_n(q1, v, acc, c.inertia, c.weight_coeff, c.a, c.b, c.h, xp),
        "u": u,
        "x_v": terms.spool,
        "p_supply": terms.p_supply,
        "power": terms.power,
        "supply_energy": y[5],
        "valve_loss_energy": y[6],
        "at_end_stop": (q1 < c.q_min) | (q1 > c.q_max) | (terms.f_stop != 0.0),
        "cavitation": (y[2] <= c.p_cav + floor_margin) | (y[3] <= c.p_cav + floor_margin),
        "relief_open": (terms.q_relief1 > 0.0) | (terms.q_relief2 > 0.0),
        "pump_saturated": terms.p_supply < c.p_supply,
    }
