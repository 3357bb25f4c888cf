"""Physical mode: the corrected boom drive with both chambers, a 4/3 valve and end stops.

State y = [q1 (m), v (m/s), z1 (Pa), z2 (Pa), x_v (spool, -1..1), E_supply (J), E_loss (J),
s (seal bristle deflection / presliding displacement), W (J), |W| (J), z_d (the drive's state),
then the energy ledger's integrals (J, ledger.INTEGRALS: battery drawn and returned, every
loss, work and stored term, and the lift's work)].
z1, z2 are the chamber pressures while the chambers are full of liquid; below the cavitation
floor they measure the void (see hydraulics.chamber_state_rate). W integrates the rate of
change of the stored energy :func:`energy` (|W| its absolute value): the energy balance the
stepping checks. z_d is the state of the drive that feeds the valve (model/drives,
``drive``): the supply line's liquid state for fixed_pump, the pump's pressure for
load_sensing; pressure_compensated starts it at p_n and reads the parameter instead (a
changed supply_pressure_pa acts at once). Pressures are absolute. What this mode corrects
in the paper's equations is listed in docs/model.md: the Lagrange equation with its m'(q1) q1'^2 / 2 term, both chambers
with volumes that follow the rod, a laminar-turbulent orifice, spool lag, supply limit,
reliefs, mass-conserving cavitation, a load-holding valve, LuGre seal friction, ambient
pressure on the rod and Hunt-Crossley end stops. Functions work on floats and, for batches,
on numpy arrays per state component (``xp=numpy`` and array-valued constants).

Equations and conventions: docs/model.md, sections "What physical mode corrects, and why".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from ..jit import compiled_as, jitable
from .drives import constants as drive_constants
from .drives import fixed_pump, load_sensing, pressure_compensated, pump_controlled
from .drives import initial_state as drive_initial_state
from .drives.constants import DriveConstants, Supply
from .end_stops import end_stop_energy_j, end_stop_force_n
from .friction import bristle_rate, seal_friction_n, stribeck_decay, stribeck_level
from .geometry import (
    annulus_area_m2,
    boom_angle_rad,
    cos_boom_angle,
    lever_derivative,
    lever_rad_per_m,
    piston_area_m2,
    sin_boom_angle,
    static_rod_force_of,
)
from .hydraulics import (
    chamber_pressure_pa,
    chamber_state_rate,
    larger,
    load_holding_flow,
    orifice_coefficient,
    pos,
    relief_flow,
    smaller,
    valve_flows,
    void_volume_m3,
)
from .ledger import INTEGRALS, Ledger, assemble, cylinder_side, electric_chain, integral_rates, valve_losses
from .mechanics import acceleration_at_lever, boom_inertia_kgm2, load_force_n
from .outputs import by_name
from .parameters import Parameters

Num = Any  # float or numpy.ndarray

STATE_NAMES = (
    "q1",
    "v",
    "p1",
    "p2",
    "x_v",
    "supply_energy",
    "valve_loss_energy",
    "bristle",
    "energy_change",
    "energy_change_abs",
    "drive_state",
    *INTEGRALS,
)
STATE_SCALES = (
    *("length", "velocity", "pressure", "pressure", "unit", "energy", "energy", "unit", "energy", "energy"),
    "pressure",
    *("energy" for _ in INTEGRALS),
)
#: Indices of W and |W| in the state: the energy balance that the stepping checks.
ENERGY_STATES = (8, 9)
#: Index of the drive's state z_d.
DRIVE_STATE = 10
#: Index of the first of the ledger's integrals (ledger.INTEGRALS, in its order).
LEDGER_STATES = 11
BATTERY_DRAWN, BATTERY_RETURNED = LEDGER_STATES, LEDGER_STATES + 1
LIFT_WORK = LEDGER_STATES + len(INTEGRALS) - 1
#: The stepping takes the substeps that :func:`stiffness_rate` asks for.
STABILITY_BOUND = True

#: Spool opening towards lowering at which the pilot has fully opened the load-holding valve.
PILOT_FULL_OPENING = 0.05


def in_use(flag: Num) -> bool:
    """Whether a 0/1 flag of the constants (a float, or an array of a batch's sets) is set for
    any set: the model skips the equations of a drive no set uses."""
    if isinstance(flag, float):
        return flag != 0.0
    return bool(np.any(flag != 0.0))


@compiled_as(in_use)
def _in_use_compiled(flag: Any) -> Any:
    """:func:`in_use` as compiled code runs it: a branch on the flag of the set (the
    implementation's annotations are those of this typing function, as numba asks)."""

    def of_set(flag: Any) -> Any:
        return np.any(flag != 0.0)

    return of_set


class Constants(NamedTuple):
    """Values derived once from :class:`Parameters` (floats, or arrays for a batch).

    The fields the valve drives read have the names of :class:`DriveConstants`' (a test
    holds them equal), so that the drive functions (model/drives) take these constants as
    their ``d``."""

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
    k_laminar: Num  # K / sqrt(p_tr): the steepest dQ/dp of a fully open path, m^3/(s Pa)
    leak: Num
    holding: Num  # 1.0 with a load-holding valve on the piston side, 0.0 without
    seat_leak: Num  # seat leakage of the closed load-holding valve, m^3/(s Pa)
    lag: Num  # 1.0 with a spool lag, 0.0 without
    inv_tau: Num  # 1 / spool time constant (0 without lag)
    p_set: Num  # p_n: the pump's pressure (pressure_compensated), the main relief's (fixed_pump), Pa
    p_tank: Num
    p_ambient: Num
    max_flow: Num  # Q_max: the pump's flow at speed, m^3/s
    p_relief: Num
    g_relief: Num
    coulomb_ratio: Num  # F_c / F_s, at least 1e-3 (1 without stiction)
    static: Num  # F_s, N
    stribeck: Num
    presliding: Num  # z_ba, m
    presliding_damping: Num  # sigma1, N s/m
    viscous: Num
    spring: Num
    spring_free: Num
    stop_k: Num
    stop_damping: Num  # Hunt-Crossley lambda, N s/m^2
    f_external: Num  # F_ext, N, positive extending (eq. 11)
    fixed: Num  # 1.0 for drive fixed_pump, else 0.0
    sensing: Num  # 1.0 for drive load_sensing, else 0.0
    speed: Num  # w_n, rad/s
    displacement: Num  # D, m^3/rad (eq. D4)
    pump_leak: Num  # G_p, m^3/(s Pa) (eq. D1)
    line_volume: Num  # V_s of fixed_pump, m^3
    g_main: Num  # main relief conductance, m^3/(s Pa) (eq. D12)
    ls_margin: Num  # load-sensing margin, Pa
    ls_inv_tau: Num  # 1 / load-sensing pump time constant, 1/s
    torque_loss: Num  # c_f of the pump (eq. D2)
    motor_copper: Num  # k_c, W/(N m)^2 (eq. D6)
    motor_iron: Num  # k_s, W/(rad/s) (eq. D6)
    battery_voltage: Num  # U, V
    battery_resistance: Num  # R, ohm
    battery_capacity: Num  # E_usable, J
    eha: Num  # 1.0 for drive pump_controlled (no valve: the pump on the chambers), else 0.0
    motor_lag: Num  # 1.0 with a motor speed lag, 0.0 without (pump_controlled, eq. D21)
    motor_inv_tau: Num  # 1 / motor time constant, 1/s
    p_reservoir: Num  # p_r, the EHA's low-pressure reservoir, Pa
    k_check: Num  # K_c of a pilot-operated check, m^3/(s Pa^0.5) (eq. D23)
    pilot_full: Num  # pilot pressure above p_r that opens a check fully, Pa (eq. D22)
    payload_inertia: Num  # the payload's share of inertia, mb L1^2, kg m^2 (eq. 8; with_payload)
    payload_weight: Num  # the payload's share of weight_coeff, mb L1 g, N m


#: The fields of Constants that are DriveConstants' too (the same values under the same names).
DRIVE_FIELDS = tuple(name for name in Constants._fields if name in DriveConstants._fields)


@jitable
def constants(p: Parameters) -> Constants:
    """Derived constants of one parameter set (compiled code calls it too: the native FMU).
    Each value that branches is computed before the call: numba compiles no keyword argument
    that branches."""
    lag = 1.0 if p.spool_time_constant_s > 0.0 else 0.0
    holding = 1.0 if p.load_holding_valve == "piston_side" else 0.0
    inv_tau = lag / p.spool_time_constant_s if lag else 0.0
    coulomb_ratio = max(p.coulomb_friction_n / p.static_friction_n, 1e-3) if p.static_friction_n > 0.0 else 1.0
    fixed = 1.0 if p.drive == "fixed_pump" else 0.0
    sensing = 1.0 if p.drive == "load_sensing" else 0.0
    eha = 1.0 if p.drive == "pump_controlled" else 0.0
    d = drive_constants(p)
    k_valve = orifice_coefficient(p.discharge_coefficient, piston_area_m2(p.orifice_diameter_m), p.density_kg_m3)
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
        k_valve=k_valve,
        transition2=p.transition_pressure_pa**2,
        k_laminar=k_valve / math.sqrt(p.transition_pressure_pa),
        leak=p.valve_leakage_m3_s_pa,
        holding=holding,
        seat_leak=p.load_holding_leakage_m3_s_pa,
        lag=lag,
        inv_tau=inv_tau,
        p_set=p.supply_pressure_pa,
        p_tank=p.tank_pressure_pa,
        p_ambient=p.ambient_pressure_pa,
        max_flow=p.pump_max_flow_m3_s,
        p_relief=p.relief_pressure_pa,
        g_relief=p.relief_rated_flow_m3_s / p.relief_range_pa,
        coulomb_ratio=coulomb_ratio,
        static=p.static_friction_n,
        stribeck=p.stribeck_velocity_m_s,
        presliding=p.friction_presliding_m,
        presliding_damping=p.friction_presliding_damping_n_s_m,
        viscous=p.viscous_friction_n_s_m,
        spring=p.spring_stiffness_n_m,
        spring_free=p.spring_free_length_m,
        stop_k=p.end_stop_stiffness_n_m,
        stop_damping=p.end_stop_damping_n_s_m2,
        f_external=p.external_rod_force_n,
        fixed=fixed,
        sensing=sensing,
        speed=d.speed,
        displacement=d.displacement,
        pump_leak=d.pump_leak,
        line_volume=d.line_volume,
        g_main=d.g_main,
        ls_margin=d.ls_margin,
        ls_inv_tau=d.ls_inv_tau,
        torque_loss=d.torque_loss,
        motor_copper=d.motor_copper,
        motor_iron=d.motor_iron,
        battery_voltage=d.battery_voltage,
        battery_resistance=d.battery_resistance,
        battery_capacity=d.battery_capacity,
        eha=eha,
        motor_lag=d.motor_lag,
        motor_inv_tau=d.motor_inv_tau,
        p_reservoir=d.p_reservoir,
        k_check=d.k_check,
        pilot_full=d.pilot_full,
        payload_inertia=boom_inertia_kgm2(0.0, p.payload_mass_kg, p.boom_length_m),
        payload_weight=p.payload_mass_kg * p.boom_length_m * p.gravity_m_s2,
    )


@jitable
def with_payload(c: Constants, share: Num) -> Constants:
    """The constants ``c`` (of the whole payload_mass_kg) with ``share`` of the payload on the
    hook (0: released): its inertia and weight scaled (eq. 8, 9), the rest unchanged."""
    off = 1.0 - share
    return Constants(*c[:3], c.inertia - off * c.payload_inertia, c.weight_coeff - off * c.payload_weight, *c[5:])


@jitable
def initial_state(p: Parameters, q1_m: float | None = None) -> list[float]:
    """Rod at rest at ``q1_m`` (default q1(0)), valve closed, seals relaxed, rod chamber at
    tank pressure, piston chamber at the pressure that holds the boom statically (eq. 6) with
    the external rod force's share taken off (eq. 11 at rest), at least tank pressure; at the
    lower end stop the boom is parked on it, with the piston chamber at tank pressure. The
    drive starts in its own initial state (model/drives: the pump was running)."""
    q1 = p.initial_length_m if q1_m is None else q1_m
    force = static_rod_force_of(p, q1)
    s1 = piston_area_m2(p.piston_diameter_m)
    s2 = annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    spring = p.spring_stiffness_n_m * (q1 - p.spring_free_length_m)
    p2 = p.tank_pressure_pa
    p1 = (force - p.external_rod_force_n + spring + p2 * s2 + p.ambient_pressure_pa * (s1 - s2)) / s1
    p1 = max(p1, p.tank_pressure_pa)  # an external force that more than carries the boom: no holding pressure
    if q1 <= p.cylinder_min_length_m:
        p1 = p.tank_pressure_pa  # parked: the stop carries the boom
    z_d = drive_initial_state(p.drive, drive_constants(p))
    return [q1, p.initial_velocity_m_s, p1, p2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, z_d] + [0.0] * len(INTEGRALS)


class Terms(NamedTuple):
    """The intermediate quantities of one evaluation, shared by derivative and observe (SI)."""

    spool: Num  # spool position seen by the flow paths, -1..1
    p1: Num  # chamber pressures, Pa (at least the cavitation floor)
    p2: Num
    vol1: Num  # chamber volumes, m^3
    vol2: Num
    dvol1: Num  # dV/dq1, m^2
    dvol2: Num
    p_supply: Num  # the valve's P-port pressure: the drive's, after the pump's flow limit, Pa
    q_pa: Num  # the spool's path flows, m^3/s (hydraulics.valve_flows)
    q_at: Num
    q_pb: Num
    q_bt: Num
    a_side: Num  # the share of the A paths' flow the load-holding valve passes
    q_valve_in: Num  # what the valve's P paths take from the drive, m^3/s
    q_in1: Num  # net flow into the piston chamber, m^3/s (eq. 12)
    q_in2: Num  # net flow into the rod chamber, m^3/s (eq. 13)
    q_relief1: Num  # port relief flows to tank, m^3/s
    q_relief2: Num
    dz1: Num  # chamber state rates, Pa/s (eq. 12, 13; see chamber_state_rate)
    dz2: Num
    f_hyd: Num  # p1 S1 - p2 S2 - p_amb (S1 - S2), N
    f_stop: Num  # end-stop force, N
    bristle_rate: Num  # ds/dt of the seals, 1/s
    f_friction: Num  # seal friction, N (opposes the motion)
    lever: Num  # k = d(alpha)/dq1, rad/m
    lever_slope: Num  # dk/dq1, rad/m^2
    cos_alpha: Num
    acc: Num  # rod acceleration, m/s^2 (eq. 11)
    power: Num  # power drawn from the supply, W
    loss: Num  # power dissipated in the valve, the load-holding valve and the reliefs, W
    supply: Supply  # the drive's supply side: its state's rate dz_d/dt, the pump (model/drives)


@jitable
def chamber_volumes(q1: Num, c: Constants, xp: ModuleType = math) -> tuple[Num, Num, Num, Num]:
    """(V1, V2, dV1/dq1, dV2/dq1): dead plus swept volume of each chamber, m^3 and m^2.

    Within the stroke V = V_dead + S x (x the stroke swept). Pressed a depth d into an end
    stop, the piston closes in on the cylinder head and the chamber shrinks as
    V_dead exp(-S d / V_dead): smoothly (dV/dq1 stays continuous, no step in the pressure
    rate at contact) and never to zero, however far the stop's compliance lets the rod go.
    """
    d1 = q1 - c.q_min
    d2 = c.q_max - q1
    e1 = xp.exp(-pos(-d1) * c.s1 / c.v1_dead)  # 1 within the stroke
    e2 = xp.exp(-pos(-d2) * c.s2 / c.v2_dead)
    return c.v1_dead * e1 + c.s1 * pos(d1), c.v2_dead * e2 + c.s2 * pos(d2), c.s1 * e1, -c.s2 * e2


@jitable(inline="always")
def _terms(y: list, c: Constants, u: Num, xp: ModuleType) -> Terms:
    """Every intermediate quantity of one evaluation, shared by derivative and observe."""
    q1, v, x_v, s = y[0], y[1], y[4], y[7]
    p1 = chamber_pressure_pa(y[2], c.p_cav)
    p2 = chamber_pressure_pa(y[3], c.p_cav)
    x = c.lag * x_v + (1.0 - c.lag) * u  # spool position seen by the flow paths
    # the P port: the pump at p_n (today's source holds the parameter's p_n, whatever z_d says) or
    # at load_sensing's pressure z_d, at most what the open path takes at its flow limit (eq. D19);
    # for fixed_pump the supply line's pressure (eq. D13)
    # (a drive no set uses is skipped, in_use: compiled, each set branches to its own drive's equations)
    z_d = y[10]
    ps = pressure_compensated.port_pressure_pa(c.p_set + c.sensing * (z_d - c.p_set), x, p1, p2, c, xp)
    if in_use(c.fixed):
        ps = ps + c.fixed * (fixed_pump.port_pressure_pa(z_d, x, p1, p2, c, xp) - ps)
    q_pa, q_at, q_pb, q_bt = valve_flows(x, ps, c.p_tank, p1, p2, c.k_valve, c.transition2, c.leak, xp)
    # the load-holding valve lets oil out of the piston chamber only when the pilot opens it
    lowering = smaller(pos(-x) / PILOT_FULL_OPENING, 1.0)
    pilot = 1.0 - c.holding + c.holding * lowering * lowering * (3.0 - 2.0 * lowering)  # smoothstep: no kink
    port_a = q_pa - q_at
    q_a = load_holding_flow(port_a, pilot, p1, c.p_tank, c.holding * c.seat_leak)
    a_side = 1.0 - (1.0 - pilot) * (port_a < 0.0)
    q_valve_in = q_pa * a_side + q_pb  # what the pump delivers through A and B
    q_r1 = relief_flow(p1, c.p_relief, c.g_relief)
    q_r2 = relief_flow(p2, c.p_relief, c.g_relief)
    q_in1 = q_a - q_r1  # Q_1 into the piston chamber
    q_in2 = q_pb - q_bt - q_r2  # -Q_2 of eq. 13: into the rod chamber
    # the drive's supply side and its state's rate: fixed_pump's line (eq. D13), load_sensing's
    # lag (eq. D18); p_n stands still
    supply = pressure_compensated.supply(z_d, ps, x, p1, p2, q_valve_in, c, xp)
    if in_use(c.fixed):
        supply = _blend(supply, fixed_pump.supply(z_d, ps, x, p1, p2, q_valve_in, c, xp), c.fixed)
    if in_use(c.sensing):
        supply = _blend(supply, load_sensing.supply(z_d, ps, x, p1, p2, q_valve_in, c, xp), c.sensing)
    line_power = 0.0 * q1
    if in_use(c.eha):
        # pump_controlled: no valve; the command sets the motor's speed, the pump and the checks feed
        # the chambers' lines (eq. D20-D24), and the valve's paths carry nothing
        flows = pump_controlled.ports(z_d, u, p1, p2, c, xp)
        supply = _blend(supply, pump_controlled.supply(z_d, u, p1, p2, flows, c, xp), c.eha)
        valve = 1.0 - c.eha
        q_pa, q_at, q_pb, q_bt, q_valve_in = valve * q_pa, valve * q_at, valve * q_pb, valve * q_bt, valve * q_valve_in
        q_in1 = q_in1 + c.eha * (flows.q_a - q_r1 - q_in1)
        q_in2 = q_in2 + c.eha * (flows.q_b - q_r2 - q_in2)
        line_power = (p1 - c.p_tank) * flows.q_a + (p2 - c.p_tank) * flows.q_b  # what the EHA gives the lines
    vol1, vol2, dvol1, dvol2 = chamber_volumes(q1, c, xp)
    dz1 = chamber_state_rate(c.bulk_modulus, vol1, q_in1, dvol1 * v, y[2], c.p_cav)  # eq. 12
    dz2 = chamber_state_rate(c.bulk_modulus, vol2, q_in2, dvol2 * v, y[3], c.p_cav)  # eq. 13
    f_hyd = p1 * c.s1 - p2 * c.s2 - c.p_ambient * (c.s1 - c.s2)
    f_stop = end_stop_force_n(q1, v, c.q_min, c.q_max, c.stop_k, c.stop_damping)
    decay = stribeck_decay(v, c.stribeck, xp)
    ratio = stribeck_level(decay, c.coulomb_ratio, 1.0)  # g(v) / F_s
    ds = bristle_rate(v, s, ratio, c.presliding)
    f_friction = seal_friction_n(v, s, ds, c.static, c.presliding, c.presliding_damping, decay, c.viscous)
    # eq. 11 without the boom load; F_ext (docs/model.md, "Mechanics") acts where f_hyd does, same sign
    f_rod = f_hyd - f_friction - c.spring * (q1 - c.spring_free) + f_stop + c.f_external
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    dk = lever_derivative(q1, c.a, c.b, xp)
    cos_alpha = cos_boom_angle(q1, c.a, c.b, c.h, xp)
    acc = acceleration_at_lever(v, f_rod, c.inertia, c.weight_coeff * cos_alpha, k, dk)  # eq. 11
    power = (ps - c.p_tank) * q_valve_in
    if in_use(c.eha):
        power = power + c.eha * line_power  # the EHA's: into the lines, above tank pressure
    loss = power - (p1 - c.p_tank) * q_in1 - (p2 - c.p_tank) * q_in2  # all not delivered to a chamber
    return Terms(
        x,
        p1,
        p2,
        vol1,
        vol2,
        dvol1,
        dvol2,
        ps,
        q_pa,
        q_at,
        q_pb,
        q_bt,
        a_side,
        q_valve_in,
        q_in1,
        q_in2,
        q_r1,
        q_r2,
        dz1,
        dz2,
        f_hyd,
        f_stop,
        ds,
        f_friction,
        k,
        dk,
        cos_alpha,
        acc,
        power,
        loss,
        supply,
    )


@jitable
def energy(y: list, c: Constants, xp: ModuleType = math) -> Num:
    """H: the energy stored in the drive, J: kinetic and potential energy of boom and
    payload, spring, seal bristles, end stops, and the compression of the oil
    V (p - p_tank)^2 / (2 E) in each chamber and in fixed_pump's supply line. Its change is
    checked against W."""
    q1, v, s = y[0], y[1], y[7]
    p1 = chamber_pressure_pa(y[2], c.p_cav)
    p2 = chamber_pressure_pa(y[3], c.p_cav)
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    vol1, vol2, _, _ = chamber_volumes(q1, c, xp)
    line = 0.0 * q1  # fixed_pump's supply line
    if in_use(c.fixed):
        ps = chamber_pressure_pa(y[10], c.p_cav)
        line = c.fixed * c.line_volume * (ps - c.p_tank) * (ps - c.p_tank) / (2.0 * c.bulk_modulus)
    return (
        0.5 * c.inertia * k * k * v * v  # T (eq. 8)
        + c.weight_coeff * sin_boom_angle(q1, c.a, c.b, c.h, xp)  # V: the moment of eq. 6 integrated over alpha
        + 0.5 * c.spring * (q1 - c.spring_free) * (q1 - c.spring_free)
        + 0.5 * c.static * c.presliding * s * s
        + end_stop_energy_j(q1, c.q_min, c.q_max, c.stop_k)
        + (vol1 * (p1 - c.p_tank) * (p1 - c.p_tank) + vol2 * (p2 - c.p_tank) * (p2 - c.p_tank)) / (2.0 * c.bulk_modulus)
        + line
    )


@jitable
def _energy_rate(y: list, c: Constants, t: Terms) -> Num:
    """dH/dt along the model's own derivative (the chain rule through :func:`energy`), W."""
    q1, v, s = y[0], y[1], y[7]
    k = t.lever
    d_low = pos(c.q_min - q1)
    d_high = pos(q1 - c.q_max)
    g1, g2 = t.p1 - c.p_tank, t.p2 - c.p_tank
    dp1 = t.dz1 * (y[2] > c.p_cav)  # the pressure stands still at the floor
    dp2 = t.dz2 * (y[3] > c.p_cav)
    line = 0.0 * q1  # fixed_pump's supply line
    if in_use(c.fixed):
        dps = t.supply.rate * (y[10] > c.p_cav)
        line = c.fixed * c.line_volume * (t.p_supply - c.p_tank) * dps / c.bulk_modulus
    return (
        c.inertia * k * v * (k * t.acc + t.lever_slope * v * v)
        + c.weight_coeff * t.cos_alpha * k * v
        + c.spring * (q1 - c.spring_free) * v
        + c.static * c.presliding * s * t.bristle_rate
        + c.stop_k * (d_high - d_low) * v
        + (t.vol1 * g1 * dp1 + t.vol2 * g2 * dp2 + 0.5 * (t.dvol1 * g1 * g1 + t.dvol2 * g2 * g2) * v) / c.bulk_modulus
        + line
    )


@jitable
def derivative(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """dy/dt of the physical model for valve command ``u`` (held over the step), as a tuple
    (compiled, it stays on the stack)."""
    terms = _terms(y, c, u, xp)
    rate = _energy_rate(y, c, terms)
    return (
        y[1],
        terms.acc,
        terms.dz1,
        terms.dz2,
        c.inv_tau * (u - y[4]),
        terms.power,
        terms.loss,
        terms.bristle_rate,
        rate,
        abs(rate),
        terms.supply.rate,
        *integral_rates(_ledger_of(y, c, terms, xp)),
    )


@jitable
def stiffness_rate(y: list, c: Constants, u: Num, dt: float, xp: ModuleType = math) -> Num:
    """An estimate of the largest eigenvalue magnitude of the Jacobian over the next ``dt``, 1/s.

    The fastest modes: a chamber against its open orifice in the laminar region
    (E / V dQ/dp), the oil springs, seals, end stop and spring against the boom's effective
    mass (sqrt(k / m)), the seal and end-stop damping (c / m), the seals' relaxation when
    sliding (|v| / (z_ba r)), the spool lag (1 / tau), fixed_pump's supply line against its
    relief, pump leakage and valve (E / V_s dQ/dp), load_sensing's lag, and pump_controlled's
    chambers against their checks and the pump's leakage, and its motor's lag. An explicit method is stable
    when dt times this stays inside its stability region (see integrators.Method).
    """
    q1, v = y[0], y[1]
    opening = larger(abs(u), abs(y[4]))  # the spool moves between its position and the command
    vol1, vol2, _, _ = chamber_volumes(q1, c, xp)
    slope = c.k_laminar * opening + 2.0 * c.leak
    # a relief valve counts where the chamber's pressure can reach it within this step
    stiff1, stiff2 = c.bulk_modulus / vol1, c.bulk_modulus / vol2
    inflow = c.max_flow  # the most the valve can feed a chamber
    relief_near1 = y[2] + stiff1 * (inflow + c.s1 * abs(v)) * dt > c.p_relief
    relief_near2 = y[3] + stiff2 * (inflow + c.s2 * abs(v)) * dt > c.p_relief
    chamber1 = stiff1 * (slope + c.g_relief * relief_near1)
    chamber2 = stiff2 * (slope + c.g_relief * relief_near2)
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    mass = c.inertia * k * k  # the boom's inertia at the rod
    reach = abs(v) * dt + 1e-4  # an end stop within reach of this step counts
    contact = (q1 < c.q_min + reach) | (q1 > c.q_max - reach)
    penetration = pos(c.q_min - q1) + pos(q1 - c.q_max) + reach
    stiffness = (
        c.bulk_modulus * (c.s1 * c.s1 / vol1 + c.s2 * c.s2 / vol2)
        + c.static / c.presliding
        + c.spring
        + c.stop_k * contact
    )
    damping = (c.presliding_damping + c.viscous + c.stop_damping * penetration * contact) / mass
    relaxation = abs(v) / (c.presliding * c.coulomb_ratio)
    rate = larger(chamber1, chamber2)
    rate = larger(rate, xp.sqrt(stiffness / mass))
    rate = larger(rate, damping)
    rate = larger(rate, relaxation)
    # fixed_pump's line: its relief where it can reach it within this step, the pump's leakage, the valve
    if in_use(c.fixed):
        line_stiffness = c.bulk_modulus / c.line_volume
        relief_near = y[10] + line_stiffness * c.max_flow * dt > c.p_set
        # the line against its relief and the pump's leakage, and against a chamber through the
        # open path: G E (1/V_s + 1/V), the two oil springs in series
        line = line_stiffness * (c.g_main * relief_near + c.pump_leak + slope) + slope * larger(stiff1, stiff2)
        rate = larger(rate, c.fixed * line)
    rate = larger(rate, c.sensing * c.ls_inv_tau)
    if in_use(c.eha):
        # pump_controlled: a chamber against its check (its laminar slope K_c / sqrt(p_tr)) and the
        # pump's cross-port leakage, and the motor's lag
        check = c.k_check * c.k_laminar / c.k_valve + c.pump_leak
        rate = larger(rate, c.eha * larger(stiff1, stiff2) * check)
        rate = larger(rate, c.eha * c.motor_inv_tau)
    return larger(rate, c.inv_tau + 0.0 * q1)


@jitable
def outputs(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """Every output of DriveState at state ``y`` (SI units; see DriveOutputs), as a tuple in the order of
    model.outputs.OUTPUT_NAMES (flags 1.0 or 0.0)."""
    terms = _terms(y, c, u, xp)
    q1, v, acc = y[0], y[1], terms.acc
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    terms_ledger = _ledger_of(y, c, terms, xp)
    void1 = void_volume_m3(c.bulk_modulus, terms.vol1, y[2], c.p_cav)
    void2 = void_volume_m3(c.bulk_modulus, terms.vol2, y[3], c.p_cav)
    return (
        t,  # t
        q1,  # q1
        v,  # v
        acc,  # a
        boom_angle_rad(q1, c.a, c.b, c.h, xp),  # alpha
        k * v,  # alpha_rate
        terms.p1,  # p1
        terms.p2,  # p2
        terms.q_in1,  # q_in1
        terms.q_in2,  # q_in2
        terms.f_hyd,  # f_hyd
        load_force_n(q1, v, acc, c.inertia, c.weight_coeff, c.a, c.b, c.h, xp),  # f_load
        terms.f_friction,  # f_friction
        u,  # u
        terms.spool,  # x_v
        terms.p_supply,  # p_supply
        terms.power,  # power
        y[5],  # supply_energy
        y[6],  # valve_loss_energy
        terms_ledger.battery_power,  # battery_power
        y[BATTERY_DRAWN],  # battery_drawn
        y[BATTERY_RETURNED],  # battery_returned
        y[LIFT_WORK],  # lift_work
        y[BATTERY_RETURNED + 1],  # reservoir_power_j
        y[BATTERY_RETURNED + 2],  # battery_loss_j
        y[BATTERY_RETURNED + 3],  # motor_loss_j
        y[BATTERY_RETURNED + 4],  # pump_volumetric_loss_j
        y[BATTERY_RETURNED + 5],  # pump_mechanical_loss_j
        y[BATTERY_RETURNED + 6],  # main_relief_loss_j
        y[BATTERY_RETURNED + 7],  # valve_loss_j
        y[BATTERY_RETURNED + 8],  # leakage_loss_j
        y[BATTERY_RETURNED + 9],  # port_relief_loss_j
        y[BATTERY_RETURNED + 10],  # friction_work_j
        y[BATTERY_RETURNED + 11],  # end_stop_work_j
        y[BATTERY_RETURNED + 12],  # ambient_work_j
        y[BATTERY_RETURNED + 13],  # external_work_j
        y[BATTERY_RETURNED + 14],  # oil_work_j
        y[BATTERY_RETURNED + 15],  # kinetic_power_j
        y[BATTERY_RETURNED + 16],  # potential_power_j
        void1,  # void1
        void2,  # void2
        1.0 * ((q1 <= c.q_min) | (q1 >= c.q_max)),  # at_end_stop: in contact (the force starts from zero)
        1.0 * ((y[2] < c.p_cav) | (y[3] < c.p_cav)),  # cavitation
        1.0 * ((terms.q_relief1 > 0.0) | (terms.q_relief2 > 0.0)),  # relief_open
        1.0 * (terms.p_supply < c.p_set + c.sensing * (y[10] - c.p_set)),  # pump_saturated: below the pump's pressure
    )


@jitable
def samples(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """The outputs the run metrics take (model.outputs.SAMPLE_NAMES, in its order), as
    :func:`outputs` gives them, without computing the others (a test holds them equal)."""
    q1 = y[0]
    p1 = chamber_pressure_pa(y[2], c.p_cav)
    p2 = chamber_pressure_pa(y[3], c.p_cav)
    relieving = (relief_flow(p1, c.p_relief, c.g_relief) > 0.0) | (relief_flow(p2, c.p_relief, c.g_relief) > 0.0)
    return (
        t,  # t
        q1,  # q1
        y[1],  # v
        boom_angle_rad(q1, c.a, c.b, c.h, xp),  # alpha
        p1,  # p1
        p2,  # p2
        u,  # u
        1.0 * ((y[2] < c.p_cav) | (y[3] < c.p_cav)),  # cavitation
        1.0 * relieving,  # relief_open
        y[5],  # supply_energy
        y[6],  # valve_loss_energy
        y[BATTERY_DRAWN],  # battery_drawn
        y[BATTERY_RETURNED],  # battery_returned
        y[LIFT_WORK],  # lift_work
    )


@jitable
def _blend(a: Supply, b: Supply, w: Num) -> Supply:
    """The supply side ``a``, or ``b`` where the drive's flag ``w`` is 1."""
    return Supply(
        a.rate + w * (b.rate - a.rate),
        a.displacement + w * (b.displacement - a.displacement),
        a.speed + w * (b.speed - a.speed),
        a.dp + w * (b.dp - a.dp),
        a.q_pump + w * (b.q_pump - a.q_pump),
        a.main_relief_loss + w * (b.main_relief_loss - a.main_relief_loss),
        a.line_oil_work + w * (b.line_oil_work - a.line_oil_work),
        a.check_loss + w * (b.check_loss - a.check_loss),
        a.reservoir_power + w * (b.reservoir_power - a.reservoir_power),
    )


@jitable
def ledger(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> Ledger:
    """The energy ledger from battery to hook at state ``y`` (docs/model.md, "Energy ledger";
    eq. D26-D29): the drive's pump through motor and inverter to the battery, the valve's and
    load-holding valve's throttling and leakage, and the cylinder to the hook, all from the
    model's own terms, so that its terms balance at every state (ledger.residual_w)."""
    return _ledger_of(y, c, _terms(y, c, u, xp), xp)


@jitable(inline="always")
def _ledger_of(y: list, c: Constants, terms: Terms, xp: ModuleType) -> Ledger:
    """:func:`ledger` from the terms of the evaluation at ``y``."""
    supply = terms.supply
    throttling, leakage = valve_losses(
        terms.q_pa,
        terms.q_at,
        terms.q_pb,
        terms.q_bt,
        terms.p_supply,
        c.p_tank,
        terms.p1,
        terms.p2,
        c.leak,
        terms.a_side,
        c.holding * c.seat_leak,
    )  # eq. D27
    throttling, leakage = throttling * (1.0 - c.eha), leakage * (1.0 - c.eha)  # pump_controlled: no valve
    cylinder = cylinder_side(
        y[1],
        terms.acc,
        terms.p1,
        terms.p2,
        terms.q_in1,
        terms.q_in2,
        terms.dvol1,
        terms.dvol2,
        terms.q_relief1,
        terms.q_relief2,
        terms.f_friction,
        terms.f_stop,
        c.spring * (y[0] - c.spring_free),
        terms.lever,
        terms.lever_slope,
        terms.cos_alpha,
        c.inertia,
        c.weight_coeff,
        c.s1,
        c.s2,
        c.p_tank,
        c.p_ambient,
        c.f_external,
    )  # eq. D28
    return assemble(electric_chain(supply, c, xp), supply, throttling, leakage, cylinder)  # eq. D26, D29


def observe(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> dict[str, Num]:
    """The outputs by name (flags as booleans): :func:`outputs` through model.outputs.by_name."""
    return by_name(outputs(t, y, c, u, xp))
