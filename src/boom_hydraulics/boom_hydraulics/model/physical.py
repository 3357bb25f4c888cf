"""Physical mode: the corrected boom drive with both chambers, a 4/3 valve and end stops.

State y = [q1 (m), v (m/s), z1 (Pa), z2 (Pa), x_v (spool, -1..1), E_supply (J), E_loss (J),
s (seal bristle deflection / presliding displacement), W (J), |W| (J), the drive's states
(drives.STATE_COUNT: z_d, z_d2, z_d3, each drive naming its own), the accumulator's fill
(model/accumulator.py; 0 without one), the hoses' (hoses.STATE_NAMES: each line's node
pressures and flows, their rates 0 without hoses), the elastic boom's (its tip deflection and
rate, 0 for a rigid boom), then the energy ledger's integrals (J,
ledger.INTEGRALS: battery drawn and returned, every loss, work and stored term, and the lift's
work)].
z1, z2 are the chamber pressures while the chambers are full of liquid; below the cavitation
floor they measure the void (see hydraulics.chamber_state_rate). W integrates the rate of
change of the stored energy :func:`energy` (|W| its absolute value): the energy balance the
stepping checks. The drive's states are those of the drive that feeds the chambers
(model/drives, ``drive``), which this module reads only through drives.supply and its
kin: a drive is one module. Pressures are absolute. What this mode corrects
in the paper's equations is listed in docs/model.md: the Lagrange equation with its m'(q1) q1'^2 / 2 term, both chambers
with volumes that follow the rod, a laminar-turbulent orifice, spool lag, supply limit,
reliefs, mass-conserving cavitation, a load-holding valve, LuGre seal friction, ambient
pressure on the rod and Hunt-Crossley end stops; a gas-charged accumulator where it is on
(docs/model.md, "Accumulator"). Functions work on floats and, for batches,
on numpy arrays per state component (``xp=numpy`` and array-valued constants).

Equations and conventions: docs/model.md, sections "What physical mode corrects, and why".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from ..jit import compiled_as, jitable, tuple_size
from . import accumulator, drives, elastic_boom, hoses
from .drives.constants import DriveConstants, Supply, in_use
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
    xi,
)
from .hydraulics import (
    chamber_pressure_pa,
    chamber_state_rate,
    larger,
    orifice_coefficient,
    pos,
    relief_flow,
    void_volume_m3,
)
from .ledger import INTEGRALS, Chain, Cylinder, Ledger, assemble, cylinder_side, electric_chain, integral_rates
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
    "drive_state_2",
    "drive_state_3",
    *INTEGRALS,
    # the model elements' states, last: a state without them (BASE_SIZE) is the states above
    "accumulator_fill",
    *hoses.STATE_NAMES,
    "boom_deflection",  # eta: the elastic boom's tip deflection, m (docs/model.md, "Elastic boom")
    "boom_deflection_rate",  # eta', m/s
)
STATE_SCALES = (
    *("length", "velocity", "pressure", "pressure", "unit", "energy", "energy", "unit", "energy", "energy"),
    *("pressure", "angular_velocity", "unit"),
    *("energy" for _ in INTEGRALS),
    "unit",
    *hoses.STATE_SCALES,
    *("length", "velocity"),
)
#: Indices of W and |W| in the state: the energy balance that the stepping checks.
ENERGY_STATES = (8, 9)
#: Index of the drive's first state z_d (drives.STATE_COUNT of them).
DRIVE_STATE = 10
DRIVE_STATES = tuple(range(DRIVE_STATE, DRIVE_STATE + drives.STATE_COUNT))
assert len(DRIVE_STATES) == 3, "the drive's states are named above, three of them"
#: Index of the accumulator's fill x = V_oil / V0 (model/accumulator.py; 0 without one): the
#: first of the model elements' states, which come last.
ACCUMULATOR_STATE = STATE_NAMES.index("accumulator_fill")
#: The size of a state without the model elements' states: where ``element_states`` is empty
#: they stand still at their initial values, and the compiled kernels step the state's first
#: BASE_SIZE components alone (solve/physical_kernel.py), so that elements off cost no step.
BASE_SIZE = ACCUMULATOR_STATE
#: Index of the hoses' first state (hoses.STATE_NAMES: line A's, then line B's), and all of them.
HOSE_STATE = STATE_NAMES.index(hoses.STATE_NAMES[0])
HOSE_STATES = tuple(range(HOSE_STATE, HOSE_STATE + len(hoses.STATE_NAMES)))
_HA, _HB = HOSE_STATE, HOSE_STATE + hoses.LINE_B
#: Indices of the elastic boom's states: its tip deflection eta and its rate (elastic_boom).
BOOM_STATE = STATE_NAMES.index("boom_deflection")
BOOM_STATES = (BOOM_STATE, BOOM_STATE + 1)
#: The units of the model elements' states (a linear model's columns).
ELEMENT_UNITS = {
    ACCUMULATOR_STATE: "1",
    **dict(zip(HOSE_STATES, hoses.STATE_UNITS)),
    **dict(zip(BOOM_STATES, ("m", "m/s"))),
}


def element_states(p: Parameters) -> tuple[int, ...]:
    """The states of the model elements ``p`` switches on (the others stand still): the
    accumulator's fill (model/accumulator.py), the hoses' (model/hoses.py), the elastic boom's
    (model/elastic_boom.py)."""
    accumulator_on = (ACCUMULATOR_STATE,) if accumulator_volume_m3(p) > 0.0 else ()
    hoses_on = HOSE_STATES if hose_length_m(p) > 0.0 else ()
    return accumulator_on + hoses_on + (BOOM_STATES if p.boom_bending_stiffness_n_m2 > 0.0 else ())


@jitable
def component(y: list, i: int) -> Num:
    """``y[i]``, or 0 where ``y`` is kept without it (a state without the model elements', see
    :data:`BASE_SIZE`): how the model reads the elements' states, inside their in_use branches
    (compiled, a constant index past a tuple's end does not compile, where this does)."""
    return y[i] if i < len(y) else 0.0 * y[0]


@jitable
def accumulator_volume_m3(p: Parameters) -> float:
    """The accumulator's size V0 in the model: ``p``'s, or 0 (none) with a drive without oil,
    whose lines it would sit on (the electro-mechanical actuator)."""
    return p.accumulator_gas_volume_m3 if drives.holds_oil(p.drive) else 0.0


@jitable
def hose_length_m(p: Parameters) -> float:
    """The hoses' length in the model: ``p``'s, or 0 (none) with a drive without oil (the
    electro-mechanical actuator has no lines)."""
    return p.hose_length_m if drives.holds_oil(p.drive) else 0.0


#: Index of the first of the ledger's integrals (ledger.INTEGRALS, in its order).
LEDGER_STATES = STATE_NAMES.index("battery_drawn")
BATTERY_DRAWN, BATTERY_RETURNED = LEDGER_STATES, LEDGER_STATES + 1
LIFT_WORK = LEDGER_STATES + len(INTEGRALS) - 1


def ledger_integrals(y: list) -> dict[str, float]:
    """The energy ledger's integrals (ledger.INTEGRALS) in the state ``y`` by name, J."""
    values = y[LEDGER_STATES : LEDGER_STATES + len(INTEGRALS)]
    return dict(zip(INTEGRALS, (float(v) for v in values), strict=True))


#: The stepping takes the substeps that :func:`stiffness_rate` asks for.
STABILITY_BOUND = True

#: The constants of the boom, cylinder and seals, in the order of :class:`Constants`' first fields.
BODY_FIELDS = (
    "a",
    "b",
    "h",
    "inertia",  # J_c1, kg m^2 (eq. 8)
    "weight_coeff",  # (m1/2 + mb) L1 g, N m
    "s1",  # piston area, m^2
    "s2",  # annulus area, m^2
    "q_min",
    "q_max",
    "v1_dead",
    "v2_dead",
    "lag",  # 1.0 with a spool lag, 0.0 without
    "inv_tau",  # 1 / spool time constant (0 without lag)
    "p_ambient",
    "p_relief",
    "g_relief",
    "coulomb_ratio",  # F_c / F_s, at least 1e-3 (1 without stiction)
    "static",  # F_s, N
    "stribeck",
    "presliding",  # z_ba, m
    "presliding_damping",  # sigma1, N s/m
    "viscous",
    "spring",
    "spring_free",
    "stop_k",
    "stop_damping",  # Hunt-Crossley lambda, N s/m^2
    "f_external",  # F_ext, N, positive extending (eq. 11)
    "payload_inertia",  # the payload's share of inertia, mb L1^2, kg m^2 (eq. 8; with_payload)
    "payload_weight",  # the payload's share of weight_coeff, mb L1 g, N m
    *hoses.HoseConstants._fields,  # the hoses (model/hoses.py; hose_on 0: none)
    # the elastic boom (docs/model.md, "Elastic boom"; elastic_boom): 1.0 on (EI > 0), 0.0 off
    "boom_on",
    "boom_stiffness",  # k_eta = 3 EI / L1^3, N/m (eq. E3)
    "boom_damping_ratio",  # zeta
    "boom_mass",  # m1, kg
    "boom_length",  # L1, m
    "gravity",  # g, m/s^2
    # the accumulator (model/accumulator.py, docs/model.md "Accumulator"): all 0 without one, its size 1
    "acc_on",  # 1.0 with an accumulator, 0.0 without
    "acc_piston",  # 1.0 on the piston-side line
    "acc_supply",  # 1.0 on the drive's supply line
    "acc_size",  # V0, m^3 (1.0 without one: nothing divides by 0)
    "acc_precharge",  # p0, Pa
    "acc_exponent",  # n
    "acc_k",  # K of its orifice, m^3/(s Pa^0.5) (eq. A3)
    "acc_slope",  # K / sqrt(p_tr): its orifice's steepest dQ/dp, m^3/(s Pa)
)

#: Values derived once from :class:`Parameters` (floats, or arrays for a batch): the boom's,
#: cylinder's and seals' (:data:`BODY_FIELDS`), then the drive's (drives.DriveConstants, under
#: the same names, so that the drive functions take these constants as their ``d``).
Constants = NamedTuple("Constants", [(name, Num) for name in (*BODY_FIELDS, *DriveConstants._fields)])  # type: ignore[misc]

#: The fields of Constants that are DriveConstants' (the same values under the same names).
DRIVE_FIELDS = DriveConstants._fields


@jitable
def constants(p: Parameters) -> Constants:
    """Derived constants of one parameter set (compiled code calls it too: the native FMU).
    Each value that branches is computed before the call: numba compiles no keyword argument
    that branches."""
    hose = hoses.hose_constants(
        *(hose_length_m(p), p.hose_inner_diameter_m, p.hose_wall_modulus_pa, p.oil_viscosity_m2_s),
        *(p.bulk_modulus_pa, p.density_kg_m3),
    )  # the hoses' oil leaves the dead volumes, which include it (eq. H1)
    lag = 1.0 if p.spool_time_constant_s > 0.0 else 0.0
    inv_tau = lag / p.spool_time_constant_s if lag else 0.0
    coulomb_ratio = max(p.coulomb_friction_n / p.static_friction_n, 1e-3) if p.static_friction_n > 0.0 else 1.0
    body = (
        *(p.a_m, p.b_m, p.support_height_m, boom_inertia_kgm2(p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m)),
        (0.5 * p.boom_mass_kg + p.payload_mass_kg) * p.boom_length_m * p.gravity_m_s2,
        *(piston_area_m2(p.piston_diameter_m), annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)),
        *(p.cylinder_min_length_m, p.cylinder_max_length_m),
        *(p.piston_dead_volume_m3 - hose.hose_chamber_share, p.rod_dead_volume_m3 - hose.hose_chamber_share),
        *(lag, inv_tau, p.ambient_pressure_pa, p.relief_pressure_pa, p.relief_rated_flow_m3_s / p.relief_range_pa),
        *(coulomb_ratio, p.static_friction_n, p.stribeck_velocity_m_s, p.friction_presliding_m),
        *(p.friction_presliding_damping_n_s_m, p.viscous_friction_n_s_m, p.spring_stiffness_n_m),
        *(p.spring_free_length_m, p.end_stop_stiffness_n_m, p.end_stop_damping_n_s_m2, p.external_rod_force_n),
        boom_inertia_kgm2(0.0, p.payload_mass_kg, p.boom_length_m),
        p.payload_mass_kg * p.boom_length_m * p.gravity_m_s2,
        *hose[:],  # [:]: a plain tuple (numba joins no named tuple to one)
        *_boom_constants(p),
    )
    volume = accumulator_volume_m3(p)
    on = 1.0 if volume > 0.0 else 0.0
    piston = on if p.accumulator_position == "piston" else 0.0
    size = volume if on else 1.0  # (computed apart: numba builds no tuple around a branch)
    k_acc = on * orifice_coefficient(
        p.discharge_coefficient, piston_area_m2(p.accumulator_orifice_diameter_m), p.density_kg_m3
    )
    slope = k_acc / math.sqrt(p.transition_pressure_pa)
    acc = (
        on,
        piston,
        on - piston,
        size,
        on * p.accumulator_precharge_pa,
        p.accumulator_polytropic_exponent,
        k_acc,
        slope,
    )
    return Constants(*body, *acc, *drives.constants(p)[:])  # [:]: a plain tuple, which numba joins to one


@jitable
def _boom_constants(p: Parameters) -> tuple:
    """The elastic boom's constants (eq. E3), in the order of BODY_FIELDS from ``boom_on``."""
    on = 1.0 if p.boom_bending_stiffness_n_m2 > 0.0 else 0.0
    stiffness = elastic_boom.modal_stiffness_n_m(p.boom_bending_stiffness_n_m2, p.boom_length_m)
    return (on, stiffness, p.boom_damping_ratio, p.boom_mass_kg, p.boom_length_m, p.gravity_m_s2)


class BoomMasses(NamedTuple):
    """The elastic boom's masses with the payload now on the hook (eq. E3; elastic_boom.modal_masses)."""

    coupling: Num  # m_c, kg m (0 off)
    modal: Num  # m_eta, kg
    participation: Num  # S, kg (0 off)
    payload: Num  # the payload on the hook, kg


@jitable
def boom_masses(c: Constants) -> BoomMasses:
    """:class:`BoomMasses` of the constants ``c``: the payload on the hook is what J holds beside
    the boom's m1 L1^2 / 3 (eq. 8), so that with_payload's share carries over."""
    length2 = c.boom_length * c.boom_length
    payload = (c.inertia - c.boom_mass * length2 / 3.0) / length2  # eq. 8
    coupling, modal, participation = elastic_boom.modal_masses(c.boom_mass, payload, c.boom_length)
    return BoomMasses(c.boom_on * coupling, modal, c.boom_on * participation, payload)


@jitable
def with_payload(c: Constants, share: Num) -> Constants:
    """The constants ``c`` (of the whole payload_mass_kg) with ``share`` of the payload on the
    hook (0: released): its inertia and weight scaled (eq. 8, 9; the elastic boom's masses
    follow J, see :func:`boom_masses`), the rest unchanged."""
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
    eta = elastic_boom.static_deflection_m(p, q1)  # the elastic boom starts bent by its weight (eq. E5 at rest)
    force = static_rod_force_of(p, q1) + elastic_boom.static_rod_force_share_n(p, q1, eta)  # eq. 6 (E4 at rest)
    s1 = piston_area_m2(p.piston_diameter_m)
    s2 = annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    spring = p.spring_stiffness_n_m * (q1 - p.spring_free_length_m)
    p2 = p.tank_pressure_pa
    p1 = (force - p.external_rod_force_n + spring + p2 * s2 + p.ambient_pressure_pa * (s1 - s2)) / s1
    p1 = max(p1, p.tank_pressure_pa)  # an external force that more than carries the boom: no holding pressure
    if q1 <= p.cylinder_min_length_m or not drives.holds_oil(p.drive):
        p1 = p.tank_pressure_pa  # parked: the stop carries the boom; or no oil: a drive's housing
    d = drives.constants(p)
    z_d = drives.initial_state(p.drive, d)
    # the accumulator holds its line's pressure (eq. A1): the piston chamber's, or the supply line's
    line = p1 if p.accumulator_position == "piston" else drives.node_pressure(z_d, d)
    fill = 0.0
    if accumulator_volume_m3(p) > 0.0:
        fill = accumulator.initial_fill(line, p.accumulator_precharge_pa, p.accumulator_polytropic_exponent)
    lines = [p1] * hoses.SEGMENTS + [0.0] * hoses.SEGMENTS + [p2] * hoses.SEGMENTS + [0.0] * hoses.SEGMENTS  # at rest
    body = [q1, p.initial_velocity_m_s, p1, p2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, z_d[0], z_d[1], z_d[2]]
    return body + [0.0] * len(INTEGRALS) + [fill] + lines + [eta, 0.0]


class Terms(NamedTuple):
    """The intermediate quantities of one evaluation, shared by derivative and observe (SI)."""

    p1: Num  # chamber pressures, Pa (at least the cavitation floor)
    p2: Num
    vol1: Num  # chamber volumes, m^3
    vol2: Num
    dvol1: Num  # dV/dq1, m^2
    dvol2: Num
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
    loss: Num  # power dissipated between the drive and the chambers (valve, load-holding valve, reliefs), W
    supply: Supply  # the drive: its states' rates, its flows and pressures, its pump and motor (model/drives)
    acc_flow: Num  # flow into the accumulator, m^3/s (eq. A3; 0 without one)
    acc_gas: Num  # its gas's pressure, Pa (eq. A1)
    acc_line: Num  # its line's pressure, Pa
    hose_a: hoses.Line  # the hose from port A to the piston chamber (its rates 0 without hoses)
    hose_b: hoses.Line  # from port B to the rod chamber
    f_rod: Num  # every force on the rod but the boom's, N (eq. 11)
    boom_acc: Num  # eta'', the elastic boom's, m/s^2 (eq. E6)
    boom_damping: Num  # c_eta, N s/m (eq. E5)
    boom_kinetic: Num  # d/dt of the elastic boom's mode's kinetic energy (eq. E1), W; 0 off
    boom_potential: Num  # d/dt of its potential energy (eq. E2), W; 0 off


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


@jitable
def drive_states(y: list) -> tuple:
    """The drive's states z (drives.STATE_COUNT of them) of the state ``y``."""
    return (y[DRIVE_STATE], y[DRIVE_STATE + 1], y[DRIVE_STATE + 2])


# inlined into its callers (and _hose_energy too), where ``first`` is a constant: called, it took
# the whole state by value and read it at indices known only at run time, which made the hoses'
# share of a derivative and of the energy 2 and 4 times what it is inlined (bench_elements)
@jitable(inline="always")
def hose_states(y: list, first: int) -> tuple:
    """(node states, flows) of the hose whose states start at ``first`` (_HA or _HB)."""
    nodes = (component(y, first), component(y, first + 1), component(y, first + 2), component(y, first + 3))
    return nodes, (component(y, first + 4), component(y, first + 5), component(y, first + 6), component(y, first + 7))


@jitable(inline="always")
def _terms(y: list, c: Constants, u: Num, xp: ModuleType) -> Terms:
    """Every intermediate quantity of one evaluation, shared by derivative and observe."""
    q1, v, x_v, s = y[0], y[1], y[4], y[7]
    p1 = chamber_pressure_pa(y[2], c.p_cav)
    p2 = chamber_pressure_pa(y[3], c.p_cav)
    x = c.lag * x_v + (1.0 - c.lag) * u  # spool position seen by the flow paths
    # the accumulator on the piston chamber or the drive's supply line (eq. A1-A4)
    acc_flow, acc_gas, acc_line = 0.0 * p1, 0.0 * p1, 0.0 * p1
    if in_use(c.acc_on):
        fill = component(y, ACCUMULATOR_STATE)
        acc_gas = accumulator.gas_pressure_pa(fill, c.acc_precharge, c.acc_exponent, xp)
        acc_line = c.acc_piston * p1 + c.acc_supply * drives.node_pressure(drive_states(y), c)
        acc_flow = c.acc_on * accumulator.port_flow_m3_s(fill, acc_line, acc_gas, c.acc_k, c.transition2, xp)
    on = c.hose_on  # with hoses the drive sees its ports' pressures, the hoses' first nodes (eq. H4)
    port_a, port_b = p1, p2
    if in_use(on):
        port_a = p1 + on * (chamber_pressure_pa(component(y, _HA), c.p_cav) - p1)
        port_b = p2 + on * (chamber_pressure_pa(component(y, _HB), c.p_cav) - p2)
    # the drive (model/drives, the set's ``drive``): its flows into the lines, its states' rates
    supply = drives.supply(drive_states(y), u, x, q1, v, port_a, port_b, c, xp, c.acc_supply * acc_flow)
    q_r1 = relief_flow(p1, c.p_relief, c.g_relief)
    q_r2 = relief_flow(p2, c.p_relief, c.g_relief)
    # Q_1 into the piston chamber: the drive's (or its hose's) less the relief and an accumulator on it
    q_in1 = supply.q_a - q_r1 - c.acc_piston * acc_flow
    q_in2 = supply.q_b - q_r2  # -Q_2 of eq. 13: into the rod chamber
    hose_a = hose_b = hoses.idle(0.0 * p1)
    if in_use(on):  # the chambers take the hoses' last flows (eq. H4-H6)
        za, qa = hose_states(y, _HA)
        zb, qb = hose_states(y, _HB)
        hose_a = hoses.line(za, qa, supply.q_a, p1, c, c.p_cav, c.p_tank)
        hose_b = hoses.line(zb, qb, supply.q_b, p2, c, c.p_cav, c.p_tank)
        q_in1 = q_in1 + on * (hose_a.end_flow - supply.q_a)
        q_in2 = q_in2 + on * (hose_b.end_flow - supply.q_b)
    vol1, vol2, dvol1, dvol2 = chamber_volumes(q1, c, xp)
    dz1 = chamber_state_rate(c.bulk_modulus, vol1, q_in1, dvol1 * v, y[2], c.p_cav)  # eq. 12
    dz2 = chamber_state_rate(c.bulk_modulus, vol2, q_in2, dvol2 * v, y[3], c.p_cav)  # eq. 13
    f_hyd = supply.cylinder * (p1 * c.s1 - p2 * c.s2 - c.p_ambient * (c.s1 - c.s2))
    f_stop = end_stop_force_n(q1, v, c.q_min, c.q_max, c.stop_k, c.stop_damping)
    decay = stribeck_decay(v, c.stribeck, xp)
    ratio = stribeck_level(decay, c.coulomb_ratio, 1.0)  # g(v) / F_s
    ds = bristle_rate(v, s, ratio, c.presliding)
    f_friction = seal_friction_n(v, s, ds, c.static, c.presliding, c.presliding_damping, decay, c.viscous)
    # eq. 11 without the boom load; F_ext (docs/model.md, "Mechanics") acts where f_hyd does, same sign,
    # and so does a drive's own force (a drive without oil)
    f_rod = f_hyd + supply.force - f_friction - c.spring * (q1 - c.spring_free) + f_stop + c.f_external
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    dk = lever_derivative(q1, c.a, c.b, xp)
    cos_alpha = cos_boom_angle(q1, c.a, c.b, c.h, xp)
    acc = acceleration_at_lever(v, f_rod, c.inertia, c.weight_coeff * cos_alpha, k, dk)  # eq. 11
    # the elastic boom's mode (elastic_boom, eq. E4-E7): 0 and the rod's acceleration untouched when off
    boom_acc, damping, boom_kinetic, boom_potential = 0.0 * q1, 0.0 * q1, 0.0 * q1, 0.0 * q1
    if in_use(c.boom_on):
        sin_alpha = sin_boom_angle(q1, c.a, c.b, c.h, xp)
        m = boom_masses(c)
        damping = elastic_boom.modal_damping_n_s_m(c.boom_damping_ratio, c.boom_stiffness, m.modal, xp)
        eta, eta_rate = component(y, BOOM_STATE), component(y, BOOM_STATE + 1)
        boom_acc, extra = elastic_boom.accelerations(
            *(f_rod, k, c.weight_coeff * cos_alpha, sin_alpha, cos_alpha, eta, eta_rate),
            *(c.inertia, m.coupling, m.modal, m.participation * c.gravity, c.boom_stiffness, damping),
        )
        acc = acc + extra
        alpha_acc = k * acc + dk * v * v
        boom_kinetic = elastic_boom.kinetic_power_w(k * v, alpha_acc, eta_rate, boom_acc, m.coupling, m.modal)
        weight = m.participation * c.gravity
        boom_potential = elastic_boom.potential_power_w(
            k * v, eta, eta_rate, sin_alpha, cos_alpha, weight, c.boom_stiffness
        )
    # all not delivered to a chamber (or to an accumulator on the piston-side line)
    loss = supply.power - (p1 - c.p_tank) * (q_in1 + c.acc_piston * acc_flow) - (p2 - c.p_tank) * q_in2
    if in_use(on):
        loss -= on * (hose_a.oil_work + hose_a.loss + hose_b.oil_work + hose_b.loss)  # nor kept by a hose
    return Terms(
        *(p1, p2, vol1, vol2, dvol1, dvol2, q_in1, q_in2, q_r1, q_r2, dz1, dz2, f_hyd, f_stop, ds, f_friction),
        *(k, dk, cos_alpha, acc, loss, supply, acc_flow, acc_gas, acc_line, hose_a, hose_b),
        *(f_rod, boom_acc, damping, boom_kinetic, boom_potential),
    )


@jitable
def energy(y: list, c: Constants, xp: ModuleType = math) -> Num:
    """H: the energy stored in the drive, J: kinetic and potential energy of boom and
    payload, spring, seal bristles, end stops, and the compression of the oil
    V (p - p_tank)^2 / (2 E) in each chamber, what the drive stores (drives.energy:
    fixed_pump's supply line) and the accumulator's gas (eq. A5). Its change is checked against W."""
    q1, v, s = y[0], y[1], y[7]
    p1 = chamber_pressure_pa(y[2], c.p_cav)
    p2 = chamber_pressure_pa(y[3], c.p_cav)
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    vol1, vol2, _, _ = chamber_volumes(q1, c, xp)
    gas = 0.0 * q1
    if in_use(c.acc_on):  # eq. A5
        fill = component(y, ACCUMULATOR_STATE)
        gas = c.acc_on * accumulator.gas_energy_j(fill, c.acc_precharge, c.acc_exponent, c.acc_size, c.p_tank, xp)
    lines, mode = 0.0 * q1, 0.0 * q1
    if in_use(c.hose_on):  # eq. H6
        lines = c.hose_on * (_hose_energy(y, _HA, c) + _hose_energy(y, _HB, c))
    if in_use(c.boom_on):  # the elastic boom's mode (eq. E1, E2)
        mode = c.boom_on * _boom_energy(y, c, k * v, xp)
    return (
        gas
        + lines
        + 0.5 * c.inertia * k * k * v * v  # T (eq. 8)
        + c.weight_coeff * sin_boom_angle(q1, c.a, c.b, c.h, xp)  # V: the moment of eq. 6 integrated over alpha
        + 0.5 * c.spring * (q1 - c.spring_free) * (q1 - c.spring_free)
        + 0.5 * c.static * c.presliding * s * s
        + end_stop_energy_j(q1, c.q_min, c.q_max, c.stop_k)
        + (vol1 * (p1 - c.p_tank) * (p1 - c.p_tank) + vol2 * (p2 - c.p_tank) * (p2 - c.p_tank)) / (2.0 * c.bulk_modulus)
        + drives.energy(drive_states(y), c, xp)  # the drive's own: fixed_pump's line, rotors
        + mode
    )


@jitable
def _boom_energy(y: list, c: Constants, alpha_rate: Num, xp: ModuleType) -> Num:
    """The elastic boom's share of H: the mode's kinetic and potential energy (eq. E1, E2), J; 0 off."""
    eta, eta_rate = component(y, BOOM_STATE), component(y, BOOM_STATE + 1)
    cos_alpha = cos_boom_angle(y[0], c.a, c.b, c.h, xp)
    m = boom_masses(c)
    return elastic_boom.kinetic_energy_j(alpha_rate, eta_rate, m.coupling, m.modal) + elastic_boom.potential_energy_j(
        eta, cos_alpha, m.participation * c.gravity, c.boom_stiffness
    )


@jitable(inline="always")
def _hose_energy(y: list, first: int, c: Constants) -> Num:
    """What the hose whose states start at ``first`` stores, J (hoses.line_energy)."""
    z, q = hose_states(y, first)
    return hoses.line_energy(z, q, c, c.p_cav, c.p_tank)


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
    mode = 0.0 * q1
    if in_use(c.boom_on):  # the elastic boom's mode (eq. E1, E2)
        mode = c.boom_on * (t.boom_kinetic + t.boom_potential)
    return (
        c.inertia * k * v * (k * t.acc + t.lever_slope * v * v)
        + c.weight_coeff * t.cos_alpha * k * v
        + c.spring * (q1 - c.spring_free) * v
        + c.static * c.presliding * s * t.bristle_rate
        + c.stop_k * (d_high - d_low) * v
        + (t.vol1 * g1 * dp1 + t.vol2 * g2 * dp2 + 0.5 * (t.dvol1 * g1 * g1 + t.dvol2 * g2 * g2) * v) / c.bulk_modulus
        + drives.energy_rate(drive_states(y), t.supply, c)
        + (t.acc_gas - c.p_tank) * t.acc_flow  # the accumulator's gas (eq. A5, A6)
        + c.hose_on * (t.hose_a.energy_rate + t.hose_b.energy_rate)
        + mode
    )


@jitable
def derivative(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """dy/dt of the physical model for valve command ``u`` (held over the step), as a tuple
    (compiled, it stays on the stack)."""
    terms = _terms(y, c, u, xp)
    rate = _energy_rate(y, c, terms)
    rates = (
        y[1],
        terms.acc,
        terms.dz1,
        terms.dz2,
        c.inv_tau * (u - y[4]),
        terms.supply.power,
        terms.loss,
        terms.bristle_rate,
        rate,
        abs(rate),
        terms.supply.rate,
        terms.supply.rate2,
        terms.supply.rate3,
        *integral_rates(_ledger_of(y, c, terms, electric_chain(terms.supply, c, xp))),
    )
    elements = (
        accumulator.fill_rate_1_s(terms.acc_flow, c.acc_size),  # eq. A2
        *_hose_rates(terms.hose_a, c.hose_on),
        *_hose_rates(terms.hose_b, c.hose_on),
        component(y, BOOM_STATE + 1),
        terms.boom_acc,
    )
    return with_elements(y, rates, elements)


def with_elements(y: list, rates: tuple, elements: tuple) -> tuple:
    """The derivative of a state of ``y``'s size: ``rates``, and the model elements' ``elements``
    after them where ``y`` holds their states (:data:`BASE_SIZE`)."""
    return rates + elements if len(y) > BASE_SIZE else rates


@compiled_as(with_elements)
def _with_elements_compiled(y: Any, rates: Any, elements: Any) -> Any:
    """:func:`with_elements` as compiled code runs it: decided on ``y``'s type, a tuple's size
    (a list, the ros2 step's state, is the whole state)."""
    size = tuple_size(y)
    if size is not None and size <= BASE_SIZE:

        def without(y: Any, rates: Any, elements: Any) -> Any:
            return rates

        return without

    def whole(y: Any, rates: Any, elements: Any) -> Any:
        return rates + elements

    return whole


@jitable
def _hose_rates(h: hoses.Line, on: Num) -> tuple:
    """The rates of one hose's states (hoses.STATE_NAMES' order), 0 without hoses."""
    return (on * h.dz0, on * h.dz1, on * h.dz2, on * h.dz3, on * h.dq1, on * h.dq2, on * h.dq3, on * h.dq4)


@jitable
def stiffness_rate(y: list, c: Constants, u: Num, dt: float, xp: ModuleType = math) -> Num:
    """An estimate of the largest eigenvalue magnitude of the Jacobian over the next ``dt``, 1/s.

    The fastest modes: a chamber against its open orifice in the laminar region
    (E / V dQ/dp), the oil springs, seals, end stop and spring against the boom's effective
    mass (sqrt(k / m)), the seal and end-stop damping (c / m), the seals' relaxation when
    sliding (|v| / (z_ba r)), the spool lag (1 / tau), the drive's own (drives.stiffness:
    how stiffly it holds each line, and its states' fastest rate), with hoses their port nodes
    against the drive and their highest wave (hoses.line_rate_1_s), an accumulator behind its
    orifice and the elastic boom's mode. An explicit method is stable
    when dt times this stays inside its stability region (see integrators.Method).
    """
    q1, v = y[0], y[1]
    opening = larger(abs(u), abs(y[4]))  # the spool moves between its position and the command
    vol1, vol2, _, _ = chamber_volumes(q1, c, xp)
    stiff1, stiff2 = c.bulk_modulus / vol1, c.bulk_modulus / vol2
    # with hoses the drive feeds their port nodes (half a segment each), and their waves count
    port1, port2, waves = stiff1, stiff2, 0.0 * stiff1
    if in_use(c.hose_on):
        port = c.hose_on * hoses.port_stiffness(c)
        port1, port2 = stiff1 + c.hose_on * (port - stiff1), stiff2 + c.hose_on * (port - stiff2)
        waves = c.hose_on * hoses.line_rate_1_s(c, larger(stiff1, stiff2), xp)
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    # the boom's inertia at the rod; the elastic boom's mode, free to bend, takes m_c^2 / m_eta off it
    mass, light, boom = c.inertia * k * k, 1e300 + 0.0 * q1, 0.0 * q1
    if in_use(c.boom_on):
        m = boom_masses(c)
        mass = (c.inertia - m.coupling * m.coupling / m.modal) * k * k
        light = mass + (1.0 - c.boom_on) * 1e300
        damping_boom = elastic_boom.modal_damping_n_s_m(c.boom_damping_ratio, c.boom_stiffness, m.modal, xp)
        boom = elastic_boom.fastest_rate(c.inertia, m.coupling, m.modal, c.boom_stiffness, damping_boom, xp)
    # the drive: how stiffly it holds each line (dQ/dp), and its own fastest rate (with the elastic
    # boom's light root at the rod against a spring of its own; none off)
    g_a, g_b, own = drives.stiffness(drive_states(y), u, opening, port1, port2, dt, c, xp, light)
    # a relief valve counts where the chamber's pressure can reach it within this step
    inflow = c.max_flow  # the most the valve can feed a chamber
    relief_near1 = y[2] + stiff1 * (inflow + c.s1 * abs(v)) * dt > c.p_relief
    relief_near2 = y[3] + stiff2 * (inflow + c.s2 * abs(v)) * dt > c.p_relief
    chamber1 = stiff1 * (g_a + c.g_relief * relief_near1)
    chamber2 = stiff2 * (g_b + c.g_relief * relief_near2)
    if in_use(c.hose_on):  # the drive's flow against the port node's oil
        chamber1 = chamber1 + c.hose_on * (port1 - stiff1) * g_a
        chamber2 = chamber2 + c.hose_on * (port2 - stiff2) * g_b
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
    rate = larger(rate, own)
    if in_use(c.acc_on):  # the accumulator's orifice between its gas spring and its line's oil spring,
        # beside the other paths that drain that line's oil: the piston chamber's relief and the drive's
        # path (with hoses the drive feeds the hose's port node instead), or the supply line's own
        line = c.acc_piston * stiff1 + c.acc_supply * c.bulk_modulus / c.line_volume
        fill = component(y, ACCUMULATOR_STATE)
        acc = accumulator.fastest_rate_1_s(fill, c.acc_precharge, c.acc_exponent, c.acc_size, line, c.acc_slope)
        piston = stiff1 * (c.g_relief * relief_near1 + (1.0 - c.hose_on) * g_a)
        rate = larger(rate, c.acc_on * (acc + c.acc_piston * piston + c.acc_supply * own))
    if in_use(c.hose_on):
        rate = larger(rate, waves)
    # the elastic boom's mode, beside the oil springs against the boom with the mode free (0 off)
    rate = larger(rate, xp.sqrt(stiffness / mass) + boom)
    return larger(rate, c.inv_tau + 0.0 * q1)


@jitable
def outputs(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> tuple:
    """Every output of DriveState at state ``y`` (SI units; see DriveOutputs), as a tuple in the order of
    model.outputs.OUTPUT_NAMES (flags 1.0 or 0.0)."""
    terms = _terms(y, c, u, xp)
    q1, v, acc = y[0], y[1], terms.acc
    k = lever_rad_per_m(q1, c.a, c.b, xp)
    chain = electric_chain(terms.supply, c, xp)  # eq. D26 (battery_overloaded: eq. D11)
    terms_ledger = _ledger_of(y, c, terms, chain)
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
        terms.supply.spool,  # x_v
        terms.supply.p_supply,  # p_supply
        terms.supply.power,  # power
        y[5],  # supply_energy
        y[6],  # valve_loss_energy
        terms_ledger.battery_power,  # battery_power
        y[BATTERY_DRAWN],  # battery_drawn
        y[BATTERY_RETURNED],  # battery_returned
        y[LIFT_WORK],  # lift_work
        y[BATTERY_RETURNED + 1],  # reservoir_power_j
        y[BATTERY_RETURNED + 2],  # battery_loss_j
        y[BATTERY_RETURNED + 3],  # motor_loss_j
        y[BATTERY_RETURNED + 4],  # standby_loss_j
        y[BATTERY_RETURNED + 5],  # pump_volumetric_loss_j
        y[BATTERY_RETURNED + 6],  # pump_mechanical_loss_j
        y[BATTERY_RETURNED + 7],  # main_relief_loss_j
        y[BATTERY_RETURNED + 8],  # valve_loss_j
        y[BATTERY_RETURNED + 9],  # leakage_loss_j
        y[BATTERY_RETURNED + 10],  # port_relief_loss_j
        y[BATTERY_RETURNED + 11],  # friction_work_j
        y[BATTERY_RETURNED + 12],  # end_stop_work_j
        y[BATTERY_RETURNED + 13],  # ambient_work_j
        y[BATTERY_RETURNED + 14],  # external_work_j
        y[BATTERY_RETURNED + 15],  # oil_work_j
        y[BATTERY_RETURNED + 16],  # rotor_power_j
        y[BATTERY_RETURNED + 17],  # kinetic_power_j
        y[BATTERY_RETURNED + 18],  # potential_power_j
        y[BATTERY_RETURNED + 19],  # accumulator_loss_j
        y[BATTERY_RETURNED + 20],  # gas_power_j
        y[BATTERY_RETURNED + 21],  # line_loss_j
        y[BATTERY_RETURNED + 22],  # structural_loss_j
        void1,  # void1
        void2,  # void2
        component(y, BOOM_STATE),  # boom_deflection
        component(y, BOOM_STATE + 1),  # boom_deflection_rate
        *_hinge_force(y, c, terms, xp),  # hinge_force_x, hinge_force_z
        1.0 * ((q1 <= c.q_min) | (q1 >= c.q_max)),  # at_end_stop: in contact (the force starts from zero)
        1.0 * ((y[2] < c.p_cav) | (y[3] < c.p_cav)),  # cavitation
        1.0 * ((terms.q_relief1 > 0.0) | (terms.q_relief2 > 0.0)),  # relief_open
        terms.supply.saturated,  # pump_saturated: below the pump's pressure
        chain.overloaded,  # battery_overloaded (eq. D11)
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
def ledger(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> Ledger:
    """The energy ledger from battery to hook at state ``y`` (docs/model.md, "Energy ledger";
    eq. D26-D29): the drive's motor through the inverter to the battery, its pump, valve or
    checks (model/drives), and the cylinder to the hook, all from the
    model's own terms, so that its terms balance at every state (ledger.residual_w)."""
    terms = _terms(y, c, u, xp)
    return _ledger_of(y, c, terms, electric_chain(terms.supply, c, xp))


@jitable
def _hinge_force(y: list, c: Constants, t: Terms, xp: ModuleType) -> tuple:
    """The hinge pin's force on the boom at O in the boom's frame (elastic_boom.hinge_force_n, eq. E8), N."""
    q1, v = y[0], y[1]
    m = boom_masses(c)
    x = xi(q1, c.a, c.b)
    rod_axial = (c.a - c.b * x) / q1  # the rod's direction, base A to eye K, in the boom's frame (eq. 1)
    rod_normal = c.b * xp.sqrt(1.0 - x * x) / q1
    eta, eta_rate = component(y, BOOM_STATE), component(y, BOOM_STATE + 1)
    # sin(alpha) of its own: the terms hold it only where the elastic boom is on (0 for a rigid boom)
    sin_alpha = sin_boom_angle(q1, c.a, c.b, c.h, xp)
    return elastic_boom.hinge_force_n(
        *(t.lever * v, t.lever * t.acc + t.lever_slope * v * v, eta, eta_rate, t.boom_acc),
        *(sin_alpha, t.cos_alpha, t.f_rod, rod_axial, rod_normal, c.boom_mass + m.payload),
        *(c.weight_coeff / c.gravity, m.participation, c.gravity),
    )


@jitable(inline="always")
def _ledger_of(y: list, c: Constants, terms: Terms, chain: Chain) -> Ledger:
    """:func:`ledger` from the terms of the evaluation at ``y`` and the drive's electric ``chain``
    (ledger.electric_chain of their supply)."""
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
    boom, structural = cylinder, 0.0 * terms.acc
    if in_use(c.boom_on):
        boom = Cylinder(
            *cylinder[:6],
            cylinder.kinetic_power + terms.boom_kinetic,
            cylinder.potential_power + terms.boom_potential,
        )  # the elastic boom's mode (eq. E1, E2), 0 off
        structural = elastic_boom.structural_loss_w(component(y, BOOM_STATE + 1), terms.boom_damping)  # eq. E5
    acc_loss = (terms.acc_line - terms.acc_gas) * terms.acc_flow  # eq. A6
    gas_power = (terms.acc_gas - c.p_tank) * terms.acc_flow
    hose_oil = c.hose_on * (terms.hose_a.oil_work + terms.hose_b.oil_work)  # eq. H6 (0 without hoses)
    hose_loss = c.hose_on * (terms.hose_a.loss + terms.hose_b.loss)
    return assemble(chain, terms.supply, boom, acc_loss, gas_power, hose_oil, hose_loss, structural)  # eq. D26, D29


def observe(t: float, y: list, c: Constants, u: Num, xp: ModuleType = math) -> dict[str, Num]:
    """The outputs by name (flags as booleans): :func:`outputs` through model.outputs.by_name."""
    return by_name(outputs(t, y, c, u, xp))
