"""The physical model's parts (model/physical.py) against their definitions in docs/model.md.

test_physical_mode.py steps the model through runs; these tests hold one evaluation at a time
to its equations at chosen states, each from its closed form: the rod's acceleration (eq. 11),
the chambers' volumes and pressure rates (eq. 12, 13, "Chambers"), the stored energy and the
energy guard's rate W' = dH/dt (the model's own derivative), the start at rest (eq. 6), the
outputs' flags at the edges that define them, the payload's share (eq. 8, 9), the model
elements switched on and off, and the stepping's stability bound where one mode is the
fastest. They run interpreted in a fraction of a second each (they are make mutants' tests of
physical.py, tools/mutants.toml)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.model import accumulator, config, drives, elastic_boom, hoses, physical
from boom_hydraulics.model.drives import DRIVES
from boom_hydraulics.model.geometry import (
    annulus_area_m2,
    boom_angle_rad,
    lever_derivative,
    lever_rad_per_m,
    piston_area_m2,
)
from boom_hydraulics.model.ledger import INTEGRALS, integral_rates
from boom_hydraulics.model.outputs import OUTPUT_NAMES
from boom_hydraulics.model.parameters import Parameters, with_updates

P = Parameters()
#: The 1 t loader crane: accumulator, hoses and elastic boom all on.
CRANE = config.load(CONFIG / "loader_crane_1t.yaml")
#: Dead volumes that hold a 1 m hose of 20 mm bore (its oil leaves them) and little else.
WIDE_HOSE_DEAD = {"piston_dead_volume_m3": 2.9e-4, "rod_dead_volume_m3": 2.9e-4}
#: A 1 m hose of 3 mm bore with oil of 200 cSt.
THIN_VISCOUS_HOSE = {"hose_length_m": 1.0, "hose_inner_diameter_m": 0.003, "oil_viscosity_m2_s": 2e-4}
#: The default boom with a spring and an external rod force, so that every force of eq. 11 is at work.
LOADED = with_updates(P, spring_stiffness_n_m=3000.0, spring_free_length_m=1.1, external_rod_force_n=-800.0)


def _state(p: Parameters, q1: float, v: float, z1: float, z2: float, spool: float = 0.0, bristle: float = 0.0) -> list:
    """The start's state of ``p`` with the rod at ``q1`` moving at ``v``, chamber states z1, z2,
    the spool at ``spool`` and the seals' bristles at ``bristle``."""
    y = list(physical.initial_state(p, q1))
    y[0], y[1], y[2], y[3], y[4], y[7] = q1, v, z1, z2, spool, bristle
    y[5], y[6], y[8], y[9] = 1234.0, 567.0, -89.0, 321.0  # energies a run has integrated (read by nothing else)
    return y


def _out(y: list, c: physical.Constants, u: float) -> dict:
    return dict(zip(OUTPUT_NAMES, physical.outputs(0.5, y, c, u)))


# ---------------------------------------------------------------------------------------------
# the rod's acceleration and the forces on the rod (docs/model.md, "Mechanics", eq. 11)


@pytest.mark.parametrize(("q1", "v", "bristle"), [(1.25, 0.07, 0.3), (1.45, -0.11, -0.6), (1.3, 0.0, 0.0)])
def test_the_rods_acceleration_is_lagranges_equation_with_every_force_on_the_rod(q1, v, bristle):
    """q1'' = (F_rod - M_g k) / (J k^2) - (k'/k) q1'^2 with F_rod = p1 S1 - p2 S2 - p_amb (S1 - S2)
    - F_friction - F_spring + F_ext (eq. 11; LuGre seals, "Friction"), each from its definition:
    J = m1 L1^2 / 3 + mb L1^2, M_g = (m1 L1 / 2 + mb L1) g cos(alpha); and the boom's load on
    the rod, f_load, is F_rod (the force balance)."""
    p = LOADED
    c = physical.constants(p)
    z1, z2 = 6.5e6, 1.2e6
    y = _state(p, q1, v, z1, z2, bristle=bristle)
    out = _out(y, c, 0.0)
    s1 = math.pi * p.piston_diameter_m**2 / 4.0
    s2 = s1 - math.pi * p.rod_diameter_m**2 / 4.0
    f_hyd = z1 * s1 - z2 * s2 - p.ambient_pressure_pa * (s1 - s2)
    # LuGre: the bristles' level g(v)/F_s = F_c/F_s + (1 - F_c/F_s) exp(-(v/v_s)^2)
    level = p.coulomb_friction_n / p.static_friction_n
    level += (1.0 - level) * math.exp(-((v / p.stribeck_velocity_m_s) ** 2))
    z_ba = p.friction_presliding_m
    bristle_rate = (v - abs(v) * bristle / level) / z_ba
    sigma1 = p.friction_presliding_damping_n_s_m * math.exp(-((v / p.stribeck_velocity_m_s) ** 2))  # it decays too
    f_friction = p.static_friction_n * bristle + sigma1 * z_ba * bristle_rate
    f_friction += p.viscous_friction_n_s_m * v
    f_spring = p.spring_stiffness_n_m * (q1 - p.spring_free_length_m)
    f_rod = f_hyd - f_friction - f_spring + p.external_rod_force_n
    inertia = p.boom_mass_kg * p.boom_length_m**2 / 3.0 + p.payload_mass_kg * p.boom_length_m**2
    alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
    moment = (0.5 * p.boom_mass_kg + p.payload_mass_kg) * p.boom_length_m * p.gravity_m_s2 * math.cos(alpha)
    k, dk = lever_rad_per_m(q1, p.a_m, p.b_m), lever_derivative(q1, p.a_m, p.b_m)
    acc = (f_rod - moment * k) / (inertia * k * k) - dk / k * v * v
    rates = physical.derivative(0.0, y, c, 0.0)
    assert rates[0] == v  # q1' = v
    assert rates[1] == pytest.approx(acc, rel=1e-9, abs=1e-12)
    assert rates[7] == pytest.approx(bristle_rate, rel=1e-12, abs=1e-12)
    assert out["a"] == rates[1]
    assert out["f_hyd"] == pytest.approx(f_hyd, rel=1e-12)
    assert out["f_friction"] == pytest.approx(f_friction, rel=1e-9, abs=1e-9)
    assert out["f_load"] == pytest.approx(f_rod, rel=1e-9)
    assert out["alpha"] == pytest.approx(alpha, rel=1e-12)
    assert out["alpha_rate"] == pytest.approx(k * v, rel=1e-12, abs=1e-15)
    assert (out["q1"], out["v"], out["t"], out["u"]) == (q1, v, 0.5, 0.0)
    assert out["p1"] == z1 and out["p2"] == z2


def test_the_end_stops_push_the_rod_out_with_hunt_crossley_and_their_contact_is_flagged_from_its_first_touch():
    """Pressed d into a stop at speed v the stop pushes k d + lambda d d' out of it ("End stops"),
    which the rod's acceleration carries (eq. 11); at_end_stop is 1 from the stop's length on
    (the force starts from zero there) and 0 a hair inside the stroke."""
    p = P
    c = physical.constants(p)
    k, lam = p.end_stop_stiffness_n_m, p.end_stop_damping_n_s_m2
    for q1, v, pushed in [(p.cylinder_max_length_m + 1e-4, 2e-3, -1.0), (p.cylinder_min_length_m - 2e-4, -3e-3, 1.0)]:
        y = _state(p, q1, v, 2e6, 2e6)
        free = _state(p, q1, v, 2e6, 2e6)
        d = abs(q1 - (p.cylinder_max_length_m if pushed < 0 else p.cylinder_min_length_m))
        force = pushed * (k * d + lam * d * abs(v))  # d' = |v|: the rod goes in deeper
        lever = lever_rad_per_m(q1, p.a_m, p.b_m)
        mass = c.inertia * lever * lever
        # the same evaluation without the stop's force is the hydraulics' and the weight's acceleration
        without = physical.derivative(0.0, free, c._replace(stop_k=0.0, stop_damping=0.0), 0.0)[1]
        assert physical.derivative(0.0, y, c, 0.0)[1] - without == pytest.approx(force / mass, rel=1e-6)
        assert _out(y, c, 0.0)["at_end_stop"] == 1.0
    for q1, flag in [(p.cylinder_min_length_m, 1.0), (p.cylinder_max_length_m, 1.0)]:
        assert _out(_state(p, q1, 0.0, 2e6, 2e6), c, 0.0)["at_end_stop"] == flag
        assert physical.observe(0.0, _state(p, q1, 0.0, 2e6, 2e6), c, 0.0)["at_end_stop"] is True
    for q1 in (p.cylinder_min_length_m + 1e-9, p.cylinder_max_length_m - 1e-9):
        assert _out(_state(p, q1, 0.0, 2e6, 2e6), c, 0.0)["at_end_stop"] == 0.0
        assert physical.observe(0.0, _state(p, q1, 0.0, 2e6, 2e6), c, 0.0)["at_end_stop"] is False


# ---------------------------------------------------------------------------------------------
# the chambers (docs/model.md, "Chambers", eq. 12, 13)


def test_the_chambers_volumes_follow_the_rod_and_shrink_exponentially_pressed_into_a_stop():
    """V1 = V1,dead + S1 (q1 - q_min), V2 = V2,dead + S2 (q_max - q1) within the stroke, with
    dV/dq1 = S1 and -S2; pressed d into a stop the chamber at that end is V_dead exp(-S d / V_dead)
    and its dV/dq1 S exp(-S d / V_dead), the other one its stroke's."""
    p = P
    c = physical.constants(p)
    s1, s2 = piston_area_m2(p.piston_diameter_m), annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    v1d, v2d, lo, hi = p.piston_dead_volume_m3, p.rod_dead_volume_m3, p.cylinder_min_length_m, p.cylinder_max_length_m
    q1 = 1.3
    got = physical.chamber_volumes(q1, c)
    assert got == pytest.approx((v1d + s1 * (q1 - lo), v2d + s2 * (hi - q1), s1, -s2), rel=1e-12)
    d = 3e-3
    e1 = math.exp(-s1 * d / v1d)
    got = physical.chamber_volumes(lo - d, c)
    assert got == pytest.approx((v1d * e1, v2d + s2 * (hi - lo + d), s1 * e1, -s2), rel=1e-12)
    e2 = math.exp(-s2 * d / v2d)
    got = physical.chamber_volumes(hi + d, c)
    assert got == pytest.approx((v1d + s1 * (hi + d - lo), v2d * e2, s1, -s2 * e2), rel=1e-12)


@pytest.mark.parametrize("drive", ["pressure_compensated", "fixed_pump"])
@pytest.mark.parametrize(("q1", "v", "u"), [(1.3, 0.05, 0.4), (1.45, -0.08, -0.7), (1.05 - 2e-3, -1e-3, 0.2)])
def test_the_chamber_pressures_change_as_eq_12_and_13_say_and_the_spool_lags_its_command(drive, q1, v, u):
    """p1' = E / V1 (Q1 - S1 q1'), p2' = E / V2 (Q2in + S2 q1') with the flows into the chambers
    (q_in1, q_in2) and the volumes of :func:`chamber_volumes`; the spool follows its command as
    x_v' = (u - x_v) / tau; the supply and valve-loss energies integrate the supply power and the
    loss (what the supply gives and the chambers do not take, "Energy accounting"); the ledger's
    integrals its terms."""
    p = with_updates(LOADED, drive=drive)
    c = physical.constants(p)
    spool = -0.25
    y = _state(p, q1, v, 7.0e6, 1.5e6, spool=spool, bristle=0.2)
    rates = physical.derivative(0.0, y, c, u)
    out = _out(y, c, u)
    vol1, vol2, dvol1, dvol2 = physical.chamber_volumes(q1, c)
    e = p.bulk_modulus_pa
    assert rates[2] == pytest.approx(e / vol1 * (out["q_in1"] - dvol1 * v), rel=1e-9)
    assert rates[3] == pytest.approx(e / vol2 * (out["q_in2"] - dvol2 * v), rel=1e-9)
    assert rates[4] == pytest.approx((u - spool) / p.spool_time_constant_s, rel=1e-12)
    assert out["x_v"] == spool  # the paths see the lagging spool
    p_t = p.tank_pressure_pa
    delivered = (7.0e6 - p_t) * out["q_in1"] + (1.5e6 - p_t) * out["q_in2"]
    assert rates[5] == out["power"]
    assert rates[6] == pytest.approx(out["power"] - delivered, rel=1e-9, abs=1e-9)
    terms = physical.ledger(0.0, y, c, u)
    got = rates[physical.LEDGER_STATES : physical.LEDGER_STATES + len(INTEGRALS)]
    assert got == tuple(integral_rates(terms))
    assert out["battery_power"] == terms.battery_power
    assert len(rates) == len(y)


def test_without_spool_lag_the_paths_see_the_command_and_the_spool_state_stands_still():
    """spool_time_constant_s 0: no lag, x_v' = 0 and the valve's paths see the command itself."""
    p = with_updates(P, spool_time_constant_s=0.0)
    c = physical.constants(p)
    y = _state(p, 1.3, 0.0, 4e6, 1e6, spool=0.3)
    assert physical.derivative(0.0, y, c, -0.6)[4] == 0.0
    assert _out(y, c, -0.6)["x_v"] == -0.6
    lagging = physical.constants(P)
    assert _out(_state(P, 1.3, 0.0, 4e6, 1e6, spool=0.3), lagging, -0.6)["x_v"] == 0.3


def test_a_cavitating_chamber_holds_the_floor_and_its_void_is_the_missing_oil():
    """Below the floor the state z measures the void, V_void = (p_cav - z) V / E, the pressure
    stays at p_cav, and z' = E / V (Q_in - V') + (p_cav - z) V' / V ("Chambers"); the flag is
    strict: at the floor no void and no cavitation."""
    p = P
    c = physical.constants(p)
    p_cav, e = p.cavitation_pressure_pa, p.bulk_modulus_pa
    q1, v = 1.3, 0.06
    z1, z2 = p_cav - 4e5, p_cav - 1e5
    y = _state(p, q1, v, z1, z2)
    out = _out(y, c, 0.0)
    vol1, vol2, dvol1, dvol2 = physical.chamber_volumes(q1, c)
    assert out["p1"] == p_cav and out["p2"] == p_cav
    assert out["void1"] == pytest.approx((p_cav - z1) * vol1 / e, rel=1e-12)
    assert out["void2"] == pytest.approx((p_cav - z2) * vol2 / e, rel=1e-12)
    assert out["cavitation"] == 1.0
    rates = physical.derivative(0.0, y, c, 0.0)
    rate1 = e / vol1 * (out["q_in1"] - dvol1 * v) + (p_cav - z1) * dvol1 * v / vol1
    rate2 = e / vol2 * (out["q_in2"] - dvol2 * v) + (p_cav - z2) * dvol2 * v / vol2
    assert rates[2] == pytest.approx(rate1, rel=1e-9)
    assert rates[3] == pytest.approx(rate2, rel=1e-9)
    for z_1, z_2, flag in [(p_cav, p_cav, 0.0), (p_cav - 1.0, 3e6, 1.0), (3e6, p_cav - 1.0, 1.0), (3e6, 2e6, 0.0)]:
        out = _out(_state(p, q1, v, z_1, z_2), c, 0.0)
        assert out["cavitation"] == flag, (z_1, z_2)
        assert physical.samples(0.0, _state(p, q1, v, z_1, z_2), c, 0.0)[7] == flag  # the run's samples alike
        assert (out["void1"] > 0.0, out["void2"] > 0.0) == (z_1 < p_cav, z_2 < p_cav)


def test_a_port_relief_opens_above_its_cracking_pressure_and_passes_its_rated_flow_at_the_top_of_its_range():
    """Q = G (p - p_crack), G = rated flow / range: a chamber at p_crack + range loses the rated
    flow to tank (q_in1 that much below the closed valve's), the flag is 1 only above p_crack, and
    the relief's flow times (p - p_tank) is booked as port relief loss."""
    p = with_updates(P, spool_time_constant_s=0.0)
    c = physical.constants(p)
    crack, span, rated = p.relief_pressure_pa, p.relief_range_pa, p.relief_rated_flow_m3_s
    at = _out(_state(p, 1.3, 0.0, crack, 1e6), c, 0.0)
    assert at["relief_open"] == 0.0
    both = _state(p, 1.3, 0.0, crack + span, crack + span)  # a flag: 1.0 with both open too
    assert _out(both, c, 0.0)["relief_open"] == 1.0 == physical.samples(0.0, both, c, 0.0)[8]
    top = crack + span
    for y in (_state(p, 1.3, 0.0, top, 1e6), _state(p, 1.3, 0.0, 1e6, top)):
        out = _out(y, c, 0.0)
        assert out["relief_open"] == 1.0
        assert physical.samples(0.0, y, c, 0.0)[8] == 1.0  # relief_open in the run's samples
        shut = _out([*y[:2], min(y[2], 1e6), min(y[3], 1e6), *y[4:]], c, 0.0)
        lost = shut["q_in1"] - out["q_in1"] + shut["q_in2"] - out["q_in2"]
        assert lost == pytest.approx(rated, rel=1e-2)  # (and the closed valve's leakage, which the pressure moves)
        loss = physical.ledger(0.0, y, c, 0.0).port_relief_loss
        assert loss == pytest.approx(rated * (top - p.tank_pressure_pa), rel=1e-9)


# ---------------------------------------------------------------------------------------------
# the stored energy and the energy guard (docs/model.md, "Energy accounting", "Stepping")


def _energy_states(p: Parameters, rng: np.random.Generator) -> list[tuple[list, float]]:
    """States where H is smooth: the rod in the stroke or pressed into a stop, moving either
    way, chambers above the floor or cavitating, the seals' bristles deflected, the elements'
    states (accumulator, hoses, elastic boom) off their start; and a command."""
    rest = physical.initial_state(p)
    lo, hi = p.cylinder_min_length_m, p.cylinder_max_length_m
    picks = []
    for q1 in (rng.uniform(lo + 0.05, hi - 0.05), lo - 1.5e-3, hi + 1e-3, rng.uniform(lo + 0.05, hi - 0.05)):
        y = [x * rng.uniform(0.9, 1.1) for x in rest]
        y[0], y[1], y[4], y[7] = q1, rng.uniform(-0.15, 0.15), rng.uniform(-1, 1), rng.uniform(-0.5, 0.5)
        y[2], y[3] = rng.uniform(1e6, 2e7), rng.uniform(-4e5, 8e6)  # z2 from a void to above tank
        if len(picks) == 3:  # each chamber cavitating once
            y[2], y[3] = -2e5, 5e6
        if len(picks) == 0:
            y[3] = -1.5e5
        if physical.BOOM_STATE in physical.element_states(p):
            y[physical.BOOM_STATE + 1] = rng.uniform(-0.05, 0.05)
        if physical.HOSE_STATE in physical.element_states(p):  # the hoses' flows, each its own
            for first in (physical.HOSE_STATE, physical.HOSE_STATE + hoses.LINE_B):
                y[first + hoses.SEGMENTS : first + 2 * hoses.SEGMENTS] = rng.uniform(-3e-4, 3e-4, hoses.SEGMENTS)
        picks.append((y, rng.uniform(-1, 1)))
    return picks


#: The elements off, all on (the crane's), or the accumulator on fixed_pump's supply line.
ELEMENTS = {
    "none": {"accumulator_gas_volume_m3": 0.0, "hose_length_m": 0.0, "boom_bending_stiffness_n_m2": 0.0},
    "all": {},
    "supply": {"accumulator_position": "supply", "accumulator_precharge_pa": 3e5},
}


@pytest.mark.parametrize(
    ("drive", "elements"), [(d, "all") for d in DRIVES] + [(d, "none") for d in DRIVES] + [("fixed_pump", "supply")]
)
def test_the_energy_guards_rate_is_the_rate_of_the_stored_energy_along_the_models_own_motion(drive, elements):
    """W' is dH/dt along the derivative (the stepping checks their integrals against each
    other): a central difference of :func:`energy` along dy/dt gives it, with the crane's
    accumulator, hoses and elastic boom on or off (or the accumulator on the supply line), a
    spring and an external force, at every drive, in the stroke and pressed into the stops,
    chambers full or cavitating; |W|' = |W'|."""
    p = with_updates(CRANE, drive=drive, spring_stiffness_n_m=2500.0, spring_free_length_m=1.5, **ELEMENTS[elements])
    c = physical.constants(p)
    h = 1e-7
    for y, u in _energy_states(p, np.random.default_rng(5)):
        f = physical.derivative(0.0, y, c, u)
        ahead = physical.energy([a + h * b for a, b in zip(y, f)], c)
        behind = physical.energy([a - h * b for a, b in zip(y, f)], c)
        w, w_abs = f[physical.ENERGY_STATES[0]], f[physical.ENERGY_STATES[1]]
        assert w == pytest.approx((ahead - behind) / (2.0 * h), rel=2e-6, abs=1e-3), (y[0], y[2], y[3])
        assert w_abs == abs(w)


def test_the_stored_energy_is_the_sum_of_its_parts():
    """H = J k^2 v^2 / 2 + (m1 L1 / 2 + mb L1) g sin(alpha) + k_s (q1 - l0)^2 / 2 + F_s z_ba s^2 / 2
    + the stops' k d^2 / 2 + sum V (p - p_tank)^2 / (2 E) (rigid boom, no elements, the default
    drive, which stores nothing of its own); a cavitating chamber stores nothing."""
    p = LOADED
    c = physical.constants(p)
    p_t, e = p.tank_pressure_pa, p.bulk_modulus_pa
    for q1, z1, z2 in [(1.3, 6e6, 2e6), (p.cylinder_max_length_m + 2e-3, 3e6, -1e5)]:
        v, s = -0.09, 0.4
        y = _state(p, q1, v, z1, z2, bristle=s)
        k = lever_rad_per_m(q1, p.a_m, p.b_m)
        inertia = p.boom_mass_kg * p.boom_length_m**2 / 3.0 + p.payload_mass_kg * p.boom_length_m**2
        weight = (0.5 * p.boom_mass_kg + p.payload_mass_kg) * p.boom_length_m * p.gravity_m_s2
        alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
        vol1, vol2, _, _ = physical.chamber_volumes(q1, c)
        p1, p2 = max(z1, p.cavitation_pressure_pa), max(z2, p.cavitation_pressure_pa)
        d = max(q1 - p.cylinder_max_length_m, 0.0)
        expected = (
            0.5 * inertia * k * k * v * v
            + weight * math.sin(alpha)
            + 0.5 * p.spring_stiffness_n_m * (q1 - p.spring_free_length_m) ** 2
            + 0.5 * p.static_friction_n * p.friction_presliding_m * s * s
            + 0.5 * p.end_stop_stiffness_n_m * d * d
            + (vol1 * (p1 - p_t) ** 2 + vol2 * (p2 - p_t) ** 2) / (2.0 * e)
        )
        assert physical.energy(y, c) == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# the start (eq. 6 at rest)


@pytest.mark.parametrize(
    "p",
    [
        P,
        LOADED,
        with_updates(P, external_rod_force_n=1500.0, payload_mass_kg=120.0),
        with_updates(P, rod_diameter_m=0.8 * P.piston_diameter_m),  # a thick rod: the annulus under S1 / 2
        CRANE,  # the elastic boom bent by its weight: E4's S g sin(alpha) eta in the holding force
    ],
)
def test_the_start_holds_the_boom_at_rest_with_the_rod_chamber_at_tank_pressure(p):
    """The start: rod at rest at q1(0), valve and spool closed, seals relaxed, energies 0, the rod
    chamber at tank pressure and the piston chamber at the pressure that holds the boom (its
    acceleration 0, eq. 6 with the spring and F_ext's shares; the elastic boom's mode at rest
    too, eq. E4 and E5)."""
    c = physical.constants(p)
    y = physical.initial_state(p)
    assert len(y) == len(physical.STATE_NAMES)
    assert y[0] == p.initial_length_m and y[1] == p.initial_velocity_m_s == 0.0
    assert y[3] == p.tank_pressure_pa and y[2] > p.tank_pressure_pa
    assert y[4:10] == [0.0] * 6
    assert y[physical.LEDGER_STATES : physical.LEDGER_STATES + len(INTEGRALS)] == [0.0] * len(INTEGRALS)
    mode = physical.BOOM_STATE + 1  # eta''
    rates = physical.derivative(0.0, y, c, 0.0)
    assert rates[1] == pytest.approx(0.0, abs=1e-9) and rates[mode] == pytest.approx(0.0, abs=1e-9)
    terms = physical.ledger(0.0, y, c, 0.0)  # at rest: no structural loss, no kinetic power
    assert terms.structural_loss == 0.0 and terms.kinetic_power == pytest.approx(0.0, abs=1e-12)
    q1 = 0.5 * (p.initial_length_m + p.cylinder_max_length_m)  # another length within the stroke
    assert physical.initial_state(p, q1)[0] == q1
    rates = physical.derivative(0.0, physical.initial_state(p, q1), c, 0.0)
    assert rates[1] == pytest.approx(0.0, abs=1e-9) and rates[mode] == pytest.approx(0.0, abs=1e-9)


def test_the_start_rests_on_the_lower_stop_on_a_force_that_carries_the_boom_and_without_oil_at_tank_pressure():
    """Parked at q_min the stop carries the boom, an external force that carries more than the
    boom leaves no holding pressure, and a drive without oil (the EMA) has its housing's: the
    piston chamber at tank pressure in each; a pump-driven start has the drive's own states."""
    for p, q1 in [
        (P, P.cylinder_min_length_m),
        (with_updates(P, external_rod_force_n=2e4), None),
        (with_updates(P, drive="electro_mechanical"), None),
    ]:
        y = physical.initial_state(p, q1)
        assert y[2] == p.tank_pressure_pa == y[3]
    p = with_updates(P, drive="pump_controlled")
    z_d = drives.initial_state(p.drive, drives.constants(p))
    assert tuple(physical.initial_state(p)[physical.DRIVE_STATE : physical.DRIVE_STATE + 3]) == tuple(z_d)
    assert physical.drive_states(physical.initial_state(p)) == tuple(z_d)


def test_the_crane_starts_with_its_hoses_at_the_chambers_pressures_its_accumulator_charged_and_its_boom_bent():
    """With the elements on: the hoses' nodes at their chamber's pressure and their flows 0, the
    accumulator's gas at its line's pressure (eq. A1: the piston chamber's, or the supply
    line's), the elastic boom bent by its weight, eta = -S g cos(alpha) / k_eta (eq. E5 at rest)."""
    for position in ("piston", "supply"):
        p = with_updates(CRANE, accumulator_position="".join(["pis", "ton"]))  # (a name built at run time, as read)
        if position == "supply":  # on fixed_pump's supply line, charged below the line's start
            p = with_updates(CRANE, accumulator_position=position, drive="fixed_pump", accumulator_precharge_pa=3e5)
        y = physical.initial_state(p)
        a, b = physical.HOSE_STATE, physical.HOSE_STATE + hoses.LINE_B
        seg = hoses.SEGMENTS
        assert y[a : a + seg] == [y[2]] * seg and y[a + seg : a + 2 * seg] == [0.0] * seg
        assert y[b : b + seg] == [y[3]] * seg and y[b + seg : b + 2 * seg] == [0.0] * seg
        c = physical.constants(p)
        line = y[2] if position == "piston" else drives.node_pressure(physical.drive_states(y), c)
        fill = y[physical.ACCUMULATOR_STATE]
        gas = accumulator.gas_pressure_pa(fill, p.accumulator_precharge_pa, p.accumulator_polytropic_exponent)
        assert gas == pytest.approx(line, rel=1e-9) and 0.0 < fill < 1.0
        eta = y[physical.BOOM_STATE]
        assert eta == elastic_boom.static_deflection_m(p, y[0]) < 0.0 and y[physical.BOOM_STATE + 1] == 0.0
    assert physical.initial_state(with_updates(CRANE, accumulator_gas_volume_m3=0.0))[physical.ACCUMULATOR_STATE] == 0.0


# ---------------------------------------------------------------------------------------------
# the payload's share and the model elements


def test_a_released_payload_takes_its_inertia_and_weight_off_the_boom():
    """with_payload(c, share): J and the weight coefficient with ``share`` of the payload (eq. 8,
    9): the whole payload is the constants themselves, none is the boom without its payload, half
    halfway; nothing else changes; boom_masses' payload on the hook is mb (eq. E3)."""
    p = with_updates(P, payload_mass_kg=150.0)
    c = physical.constants(p)
    empty = physical.constants(with_updates(p, payload_mass_kg=0.0))
    assert physical.with_payload(c, 1.0) == c
    none = physical.with_payload(c, 0.0)
    assert none.inertia == pytest.approx(empty.inertia, rel=1e-12)
    assert none.weight_coeff == pytest.approx(empty.weight_coeff, rel=1e-12)
    half = physical.with_payload(c, 0.5)
    assert half.inertia == pytest.approx(0.5 * (c.inertia + empty.inertia), rel=1e-12)
    assert half.weight_coeff == pytest.approx(0.5 * (c.weight_coeff + empty.weight_coeff), rel=1e-12)
    assert half[:3] == c[:3] and half[5:] == c[5:]
    assert physical.boom_masses(c).payload == pytest.approx(150.0, rel=1e-12)
    assert physical.boom_masses(none).payload == pytest.approx(0.0, abs=1e-12)


def test_the_elements_switched_on_are_the_states_that_move_and_a_state_without_them_steps_alone():
    """element_states: none by default; the crane's accumulator, hoses and elastic boom; a drive
    without oil keeps only the elastic boom (no lines for the others). A state of BASE_SIZE (the
    elements off) has a derivative of its own size and reads the elements' states as 0."""
    assert physical.element_states(P) == ()
    assert physical.element_states(CRANE) == (physical.ACCUMULATOR_STATE, *physical.HOSE_STATES, *physical.BOOM_STATES)
    ema = with_updates(CRANE, drive="electro_mechanical")
    assert physical.element_states(ema) == physical.BOOM_STATES
    assert physical.accumulator_volume_m3(ema) == 0.0 and physical.hose_length_m(ema) == 0.0
    assert physical.accumulator_volume_m3(CRANE) == CRANE.accumulator_gas_volume_m3 > 0.0
    assert physical.hose_length_m(CRANE) == CRANE.hose_length_m > 0.0
    assert physical.element_states(with_updates(CRANE, hose_length_m=0.0, boom_bending_stiffness_n_m2=0.0)) == (
        physical.ACCUMULATOR_STATE,
    )
    c = physical.constants(P)
    y = physical.initial_state(P)
    base = y[: physical.BASE_SIZE]
    assert len(physical.derivative(0.0, base, c, 0.3)) == physical.BASE_SIZE
    assert physical.derivative(0.0, base, c, 0.3) == physical.derivative(0.0, y, c, 0.3)[: physical.BASE_SIZE]
    assert physical.component(base, physical.BOOM_STATE) == 0.0 and physical.component(y, 1) == y[1]
    assert physical.component(base, physical.ACCUMULATOR_STATE) == 0.0  # the first past its end
    # lowering (v < 0), a state without them still publishes a rigid boom's deflection as 0.0, not -0.0
    lowering = [*base[:1], -0.1, *base[2:-1], -5.0]  # (the lift's work, last, below 0 too)
    out = _out(lowering, c, 0.0)
    assert (repr(out["boom_deflection"]), repr(out["boom_deflection_rate"])) == ("0.0", "0.0")
    rates = physical.derivative(0.0, y, c, 0.3)
    assert rates[physical.BASE_SIZE :] == (0.0,) * (len(y) - physical.BASE_SIZE)


def test_the_elastic_booms_deflection_moves_at_its_rate_and_is_published():
    """eta' is the state eta_rate, published as boom_deflection and boom_deflection_rate."""
    c = physical.constants(CRANE)
    y = physical.initial_state(CRANE)
    y[physical.BOOM_STATE], y[physical.BOOM_STATE + 1] = -0.02, 0.037
    rates = physical.derivative(0.0, y, c, 0.0)
    assert rates[physical.BOOM_STATE] == 0.037
    out = _out(y, c, 0.0)
    assert (out["boom_deflection"], out["boom_deflection_rate"]) == (-0.02, 0.037)


def test_the_ledgers_integrals_are_read_by_name():
    """ledger_integrals: the state's ledger integrals (ledger.INTEGRALS) by name, J."""
    y = list(physical.initial_state(P))
    for k in range(len(INTEGRALS)):
        y[physical.LEDGER_STATES + k] = 10.0 + k
    assert physical.ledger_integrals(y) == {name: 10.0 + k for k, name in enumerate(INTEGRALS)}
    with pytest.raises(ValueError):  # a state cut short names no fewer integrals: it is refused
        physical.ledger_integrals(y[: physical.LIFT_WORK])
    assert physical.LIFT_WORK == physical.LEDGER_STATES + INTEGRALS.index("lift_work")
    assert physical.BATTERY_RETURNED == physical.LEDGER_STATES + INTEGRALS.index("battery_returned")


# ---------------------------------------------------------------------------------------------
# the hinge force (docs/model.md, "Elastic boom", eq. E8)


@pytest.mark.parametrize(("q1", "v", "payload_kg"), [(1.37, 0.0, 50.0), (1.6, 0.0, 0.0), (1.5, 0.12, 200.0)])
def test_the_hinge_force_of_a_rigid_boom_is_newtons_law_for_boom_and_payload(q1, v, payload_kg):
    """R = sum(m a) - (m1 + mb) g - F_rod e_rod (eq. E8) for a rigid boom in its own frame (x to
    the tip, z normal): the weight's share along the boom (m1 + mb) g sin(alpha) and normal to it
    (m1 + mb) g cos(alpha), the rod's force along e_rod = (a - b xi, b sqrt(1 - xi^2)) / q1, and
    the centre of mass's acceleration (-M1 alpha'^2, M1 alpha''), M1 = m1 L1 / 2 + mb L1; at
    rest the boom's statics."""
    p = with_updates(P, payload_mass_kg=payload_kg)
    c = physical.constants(p)
    y = _state(p, q1, v, 5.5e6, 1.0e6)
    out = _out(y, c, 0.0)
    alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
    mass = p.boom_mass_kg + payload_kg
    first_moment = (0.5 * p.boom_mass_kg + payload_kg) * p.boom_length_m
    xi = (p.a_m**2 + p.b_m**2 - q1 * q1) / (2.0 * p.a_m * p.b_m)  # eq. 1
    e_rod = ((p.a_m - p.b_m * xi) / q1, p.b_m * math.sqrt(1.0 - xi * xi) / q1)
    k, dk = lever_rad_per_m(q1, p.a_m, p.b_m), lever_derivative(q1, p.a_m, p.b_m)
    alpha_rate, alpha_acc = k * v, k * out["a"] + dk * v * v
    f_rod = out["f_load"]  # every force on the rod but the boom's (the force balance, above)
    g = p.gravity_m_s2
    expected_x = -first_moment * alpha_rate**2 + mass * g * math.sin(alpha) - f_rod * e_rod[0]
    expected_z = first_moment * alpha_acc + mass * g * math.cos(alpha) - f_rod * e_rod[1]
    assert out["hinge_force_x"] == pytest.approx(expected_x, rel=1e-9)
    assert out["hinge_force_z"] == pytest.approx(expected_z, rel=1e-9)


# ---------------------------------------------------------------------------------------------
# the elastic boom's mode (docs/model.md, "Elastic boom", eq. E3-E7)


@pytest.mark.parametrize(("v", "eta", "eta_rate"), [(0.05, -0.012, 0.02), (-0.08, -0.02, -0.04)])
def test_the_elastic_booms_mode_and_the_rod_follow_e4_to_e7(v, eta, eta_rate):
    """With the mode on (the crane, EI > 0): eta'' = (J R_eta - m_c R_alpha) / (J m_eta - m_c^2)
    (E6) with R_alpha = F_rod / k - M_g + S g sin(alpha) eta (E4) and R_eta = -k_eta eta - c_eta eta'
    - S g cos(alpha) (E5), k_eta = 3 EI / L1^3, c_eta = 2 zeta sqrt(k_eta m_eta), the masses of E3 with
    the payload on the hook; the rod's acceleration is the rigid boom's plus
    (S g sin(alpha) eta - m_c eta'') / (J k) (E7)."""
    p = CRANE
    c = physical.constants(p)
    q1 = 1.8
    y = _state(p, q1, v, 9.0e6, 1.5e6)
    y[physical.BOOM_STATE], y[physical.BOOM_STATE + 1] = eta, eta_rate
    rigid = physical.derivative(0.0, y, c._replace(boom_on=0.0), 0.0)
    rates = physical.derivative(0.0, y, c, 0.0)
    f_rod = _out(y, c._replace(boom_on=0.0), 0.0)["f_load"]  # every force on the rod but the boom's
    m1, mb, length, g = p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m, p.gravity_m_s2
    inertia = m1 * length**2 / 3.0 + mb * length**2
    coupling, modal, participation = elastic_boom.modal_masses(m1, mb, length)
    k_eta = 3.0 * p.boom_bending_stiffness_n_m2 / length**3
    c_eta = 2.0 * p.boom_damping_ratio * math.sqrt(k_eta * modal)
    alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
    k = lever_rad_per_m(q1, p.a_m, p.b_m)
    r_alpha = f_rod / k - (0.5 * m1 + mb) * length * g * math.cos(alpha) + participation * g * math.sin(alpha) * eta
    r_eta = -k_eta * eta - c_eta * eta_rate - participation * g * math.cos(alpha)
    eta_acc = (inertia * r_eta - coupling * r_alpha) / (inertia * modal - coupling**2)
    assert rates[physical.BOOM_STATE] == eta_rate
    assert rates[physical.BOOM_STATE + 1] == pytest.approx(eta_acc, rel=1e-9)
    extra = (participation * g * math.sin(alpha) * eta - coupling * eta_acc) / (inertia * k)
    assert rates[1] == pytest.approx(rigid[1] + extra, rel=1e-9)
    # the structure's damping is the ledger's structural loss, c_eta eta'^2 (eq. E5)
    assert physical.ledger(0.0, y, c, 0.0).structural_loss == pytest.approx(c_eta * eta_rate**2, rel=1e-9)
    masses = physical.boom_masses(c)
    assert masses == pytest.approx((coupling, modal, participation, mb), rel=1e-12)
    off = physical.boom_masses(c._replace(boom_on=0.0))
    assert (off.coupling, off.participation) == (0.0, 0.0)


# ---------------------------------------------------------------------------------------------
# the valve's loss, a floor of zero


@pytest.mark.parametrize("p", [LOADED, CRANE])
def test_the_valve_loss_energy_grows_by_the_valves_leakages_and_reliefs_loss_beside_the_hoses(p):
    """valve_loss_energy' is what the supply gives and the chambers (and, with them on, the hoses
    and an accumulator on the piston's line) do not keep: with today's valve drive, the ledger's
    valve loss, leakage loss and port relief loss (docs/model.md, "Energy accounting"), the hoses'
    flows and losses and the reliefs at work."""
    c = physical.constants(p)
    rng = np.random.default_rng(3)
    for z1 in (9.0e6, p.relief_pressure_pa + 0.4 * p.relief_range_pa):
        y = _state(p, 1.5 if p is CRANE else 1.3, 0.05, z1, 1.2e6, spool=0.4)
        for i in physical.HOSE_STATES if p is CRANE else ():
            y[i] = y[i] * rng.uniform(0.8, 1.2) + rng.uniform(-2e-4, 2e-4)  # the hoses' pressures and flows
        rates = physical.derivative(0.0, y, c, 0.5)
        terms = physical.ledger(0.0, y, c, 0.5)
        lost = terms.valve_loss + terms.leakage_loss + terms.port_relief_loss
        assert rates[6] == pytest.approx(lost, rel=1e-9)
        assert lost > 0.0 and (terms.port_relief_loss > 0.0) == (z1 > p.relief_pressure_pa)
        if p is CRANE:
            assert terms.line_loss > 0.0


def test_a_chamber_drawn_to_a_floor_of_zero_reads_zero_pressure_and_stays_finite():
    """cavitation_pressure_pa 0 (a perfect vacuum): a chamber drawn below it reads 0 Pa, its void
    is -z V / E, and every output and rate stays finite."""
    p = with_updates(P, cavitation_pressure_pa=0.0)
    c = physical.constants(p)
    for z1, z2 in [(0.0, 3e6), (-2e5, 0.0), (0.0, 0.0)]:
        y = _state(p, 1.3, -0.05, z1, z2)
        out = _out(y, c, -0.3)
        assert out["p1"] == max(z1, 0.0) and out["p2"] == max(z2, 0.0)
        assert all(math.isfinite(x) for x in physical.outputs(0.0, y, c, -0.3))
        assert all(math.isfinite(x) for x in physical.derivative(0.0, y, c, -0.3))
        assert math.isfinite(physical.stiffness_rate(y, c, -0.3, p.time_step_s))
        # no accumulator, hoses or elastic boom: their rates and the ledger's terms of them stay 0
        rates = physical.derivative(0.0, y, c, -0.3)
        assert rates[physical.BASE_SIZE :] == (0.0,) * (len(y) - physical.BASE_SIZE)
        terms = physical.ledger(0.0, y, c, -0.3)
        assert (terms.accumulator_loss, terms.gas_power, terms.line_loss, terms.structural_loss) == (0.0,) * 4
        assert out["cavitation"] == (1.0 if min(z1, z2) < 0.0 else 0.0)


# ---------------------------------------------------------------------------------------------
# the stepping's stability bound (stiffness_rate; docs/model.md, "Stepping")


#: A 1 L accumulator on the supply line, pre-charged far below the line's pressure.
SUPPLY_ACCUMULATOR = {
    "accumulator_position": "supply",
    "accumulator_gas_volume_m3": 1e-3,
    "accumulator_precharge_pa": 3e5,
}


def _largest_eigenvalue(y: list, c: physical.Constants, u: float) -> float:
    """The largest |lambda| of the derivative's Jacobian at ``y`` over the states that move the
    model (central differences)."""
    moving = [i for i, kind in enumerate(physical.STATE_SCALES) if kind != "energy"]
    columns = []
    for i in moving:
        h = 1.0 if physical.STATE_SCALES[i] == "pressure" else 1e-7
        ahead, behind = list(y), list(y)
        ahead[i] += h
        behind[i] -= h
        fa, fb = physical.derivative(0.0, ahead, c, u), physical.derivative(0.0, behind, c, u)
        columns.append([(fa[k] - fb[k]) / (2.0 * h) for k in moving])
    return float(np.max(np.abs(np.linalg.eigvals(np.array(columns).T))))


@pytest.mark.parametrize(
    ("p", "q1", "v", "u", "spool", "most"),
    [
        (P, None, 0.0, 0.0, 0.0, 1.35),  # at rest: the spool's lag
        (P, 1.37, 0.05, 0.6, 0.6, 1.35),  # the open valve's chambers
        (P, 1.37, 0.0, 0.0, 0.0, 1.35),  # at rest in mid-stroke: the oil springs
        (with_updates(P, accumulator_gas_volume_m3=1e-3, accumulator_precharge_pa=2e6), None, 0.0, 0.3, 0.3, 1.35),
        (with_updates(P, drive="fixed_pump"), 1.37, 0.05, 0.6, 0.6, 1.35),  # its supply line
        # an accumulator on that line: its orifice beside the relief's and the valve's paths
        (with_updates(P, drive="fixed_pump", **SUPPLY_ACCUMULATOR), None, 0.0, 0.0, 0.0, 1.35),
        (with_updates(P, drive="fixed_pump", **SUPPLY_ACCUMULATOR), 1.37, 0.05, 0.6, 0.6, 1.35),
        (CRANE, 1.8, 0.1, 0.3, 0.3, 1.35),  # the hoses' port nodes and the elastic boom
        (CRANE, 1.8, 0.0, 0.05, 0.05, 1.35),  # the hoses' highest wave (the valve barely open)
        (CRANE, 1.8, 0.05, 1.0, 1.0, 1.35),  # the hoses' port nodes against the valve wide open
        (CRANE, 1.8, 0.05, 0.0, 1.0, 1.35),  # the spool still wide open, closing on a command to close
        # a thin hose of viscous oil: the highest wave with its friction's R / I (711 1/s) beside it
        (with_updates(P, **THIN_VISCOUS_HOSE), 1.37, 0.0, 0.0, 0.0, 1.35),
        # a wide hose's last flow into a piston chamber near its end of stroke, six times stiffer than a node
        (with_updates(P, hose_length_m=1.0, hose_inner_diameter_m=0.02, **WIDE_HOSE_DEAD), 1.052, 0.0, 0.0, 0.0, 1.5),
        # where the bound adds rates, within about twice: the EMA's screw against the elastic boom's light
        # root, and without hoses that root on the oil springs, their rate plus the mode's
        (with_updates(CRANE, drive="electro_mechanical"), 1.8, 0.0, 0.0, 0.0, 2.0),
        (with_updates(CRANE, hose_length_m=0.0), None, 0.0, 0.0, 0.0, 2.1),
    ],
)
def test_the_stability_bound_covers_the_fastest_mode_and_is_tight_where_one_mode_dominates(p, q1, v, u, spool, most):
    """stiffness_rate is the Jacobian's largest |lambda| or more (else an explicit method rings up;
    to 1 %, the margin of the methods' stability limits, where two modes couple) and, where one of
    the modes it names dominates, no more than 1.35 times it (else the run takes needless substeps;
    about twice where it adds the rates of coupled modes); the spool counts as open as it is or as
    its command, whichever is wider."""
    c = physical.constants(p)
    y = list(physical.initial_state(p, q1))
    y[1], y[4] = v, spool
    if q1 is not None:
        y[2], y[3] = 8e6, 2e6
    lam = _largest_eigenvalue(y, c, u)
    assert 0.99 * lam <= physical.stiffness_rate(y, c, u, p.time_step_s) <= most * lam


def test_the_stability_bound_is_the_spool_lags_rate_or_the_stops_damping_where_either_is_fastest():
    """With a fast spool (tau 10 us) the bound is 1 / tau; pressed into a stop with its damping
    the fastest mode, (sigma1 + b_d + lambda (d + |v| dt + 0.1 mm)) / (J k^2): the stop's
    Hunt-Crossley damping at the depth this step can reach, against the boom's mass at the rod."""
    fast = with_updates(P, spool_time_constant_s=1e-5)
    c = physical.constants(fast)
    assert physical.stiffness_rate(physical.initial_state(fast), c, 0.5, fast.time_step_s) == pytest.approx(
        1e5, rel=1e-12
    )
    p = with_updates(P, end_stop_damping_n_s_m2=1e11, spool_time_constant_s=0.0)
    c = physical.constants(p)
    dt = p.time_step_s
    for q1, v in [(p.cylinder_min_length_m - 5e-4, -0.01), (p.cylinder_max_length_m + 3e-4, 0.02)]:
        y = _state(p, q1, v, 2e6, 2e6)
        d = max(p.cylinder_min_length_m - q1, q1 - p.cylinder_max_length_m)
        k = lever_rad_per_m(q1, p.a_m, p.b_m)
        mass = c.inertia * k * k
        damping = p.friction_presliding_damping_n_s_m + p.viscous_friction_n_s_m
        damping += p.end_stop_damping_n_s_m2 * (d + abs(v) * dt + 1e-4)
        assert physical.stiffness_rate(y, c, 0.0, dt) == pytest.approx(damping / mass, rel=1e-9)


def test_a_relief_counts_in_the_bound_from_where_this_step_can_reach_its_cracking_pressure():
    """A port relief's E / V G counts where the chamber's pressure can reach p_crack within the
    step: z + E / V (Q_max + S |v|) dt > p_crack, Q_max the most the valve can feed it; a hair
    short of that reach it does not (the spool closed, the relief the fastest mode there)."""
    p = with_updates(P, spool_time_constant_s=0.0)
    c = physical.constants(p)
    dt, q1, v = p.time_step_s, 1.3, 0.04
    vol1, vol2, _, _ = physical.chamber_volumes(q1, c)
    g = p.relief_rated_flow_m3_s / p.relief_range_pa
    for chamber, vol, area in [(2, vol1, c.s1), (3, vol2, c.s2)]:
        reach = p.bulk_modulus_pa / vol * (c.max_flow + area * abs(v)) * dt
        bounds = []
        for short in (0.999, 1.001):
            y = _state(p, q1, v, 1e6, 1e6)
            y[chamber] = p.relief_pressure_pa - short * reach
            bounds.append(physical.stiffness_rate(y, c, 0.0, dt))
        relief = p.bulk_modulus_pa / vol * g
        assert bounds[0] >= relief > bounds[1], chamber


@pytest.mark.parametrize(("v", "eta", "eta_rate"), [(0.06, -0.015, 0.03), (-0.04, -0.01, -0.02)])
def test_the_hinge_force_of_the_elastic_boom_adds_the_modes_share(v, eta, eta_rate):
    """Eq. E8 with the mode on: the mode adds S (eta'' - alpha'^2 eta) normal to the boom and
    -S (2 alpha' eta' + alpha'' eta) along it, to the rigid boom's Newton for boom and payload."""
    p = CRANE
    c = physical.constants(p)
    q1 = 1.8
    y = _state(p, q1, v, 9.0e6, 1.5e6)
    y[physical.BOOM_STATE], y[physical.BOOM_STATE + 1] = eta, eta_rate
    out = _out(y, c, 0.0)
    f_rod = _out(y, c._replace(boom_on=0.0), 0.0)["f_load"]  # every force on the rod but the boom's
    eta_acc = physical.derivative(0.0, y, c, 0.0)[physical.BOOM_STATE + 1]
    m1, mb, length, g = p.boom_mass_kg, p.payload_mass_kg, p.boom_length_m, p.gravity_m_s2
    participation = elastic_boom.modal_masses(m1, mb, length)[2]
    first_moment = (0.5 * m1 + mb) * length
    alpha = boom_angle_rad(q1, p.a_m, p.b_m, p.support_height_m)
    xi = (p.a_m**2 + p.b_m**2 - q1 * q1) / (2.0 * p.a_m * p.b_m)  # eq. 1
    e_rod = ((p.a_m - p.b_m * xi) / q1, p.b_m * math.sqrt(1.0 - xi * xi) / q1)
    k, dk = lever_rad_per_m(q1, p.a_m, p.b_m), lever_derivative(q1, p.a_m, p.b_m)
    alpha_rate, alpha_acc = k * v, k * out["a"] + dk * v * v
    along = -first_moment * alpha_rate**2 - participation * (2.0 * alpha_rate * eta_rate + alpha_acc * eta)
    normal = first_moment * alpha_acc + participation * (eta_acc - alpha_rate**2 * eta)
    assert out["hinge_force_x"] == pytest.approx(along + (m1 + mb) * g * math.sin(alpha) - f_rod * e_rod[0], rel=1e-9)
    assert out["hinge_force_z"] == pytest.approx(normal + (m1 + mb) * g * math.cos(alpha) - f_rod * e_rod[1], rel=1e-9)


def test_with_hoses_the_chambers_dead_volumes_give_up_the_lines_oil_but_half_a_segment():
    """The hoses' oil, but the half segment at each port, is their own states' (eq. H1): each
    chamber's dead volume is the set's less (N - 1/2) A l, A the hose's bore, l its segment."""
    p = CRANE
    c = physical.constants(p)
    segment = p.hose_length_m / hoses.SEGMENTS
    share = (hoses.SEGMENTS - 0.5) * math.pi * p.hose_inner_diameter_m**2 / 4.0 * segment
    q1 = 1.7
    vol1, vol2, _, _ = physical.chamber_volumes(q1, c)
    s1, s2 = piston_area_m2(p.piston_diameter_m), annulus_area_m2(p.piston_diameter_m, p.rod_diameter_m)
    assert vol1 == pytest.approx(p.piston_dead_volume_m3 - share + s1 * (q1 - p.cylinder_min_length_m), rel=1e-12)
    assert vol2 == pytest.approx(p.rod_dead_volume_m3 - share + s2 * (p.cylinder_max_length_m - q1), rel=1e-12)


@pytest.mark.parametrize(
    ("static_n", "coulomb_n", "level"), [(150.0, 100.0, 100.0 / 150.0), (150.0, 0.0, 1e-3), (0.0, 0.0, 1.0)]
)
def test_sliding_fast_the_seals_bristles_settle_at_the_coulomb_level_floored_at_a_thousandth(
    static_n, coulomb_n, level
):
    """Sliding at 1 m/s (far past the Stribeck speed) the bristles move as
    ds/dt = (v - |v| s / r) / z_ba with r = F_c / F_s ("Friction"): at least 1e-3 (no division by
    a Coulomb force of 0), and 1 without stiction (F_s = 0)."""
    p = with_updates(P, static_friction_n=static_n, coulomb_friction_n=coulomb_n)
    c = physical.constants(p)
    y = _state(p, 1.3, 1.0, 4e6, 1e6, bristle=0.4e-3)
    assert physical.derivative(0.0, y, c, 0.0)[7] == pytest.approx(
        (1.0 - 0.4e-3 / level) / p.friction_presliding_m, rel=1e-9
    )


def test_compiled_code_adds_the_elements_rates_to_a_state_longer_than_the_base_and_a_list_always():
    """How compiled code decides with_elements on the state's type (its typing function, run
    as Python): a tuple of BASE_SIZE or fewer (the kernels' state with the elements off) gets the
    rates alone, a longer one the elements' rates after them, and a list (the ros2 step's whole
    state) the elements' too; the interpreted with_elements decides on the length alike."""
    types = pytest.importorskip("numba").types
    rates, elements = (1.0, 2.0), (3.0,)
    for size, whole in [(physical.BASE_SIZE - 1, False), (physical.BASE_SIZE, False), (physical.BASE_SIZE + 1, True)]:
        typed = types.UniTuple(types.float64, size)
        chosen = physical._with_elements_compiled(
            typed, types.UniTuple(types.float64, 2), types.UniTuple(types.float64, 1)
        )
        assert chosen(None, rates, elements) == ((1.0, 2.0, 3.0) if whole else rates), size
        assert physical.with_elements([0.0] * size, rates, elements) == chosen(None, rates, elements)
    listed = physical._with_elements_compiled(types.List(types.float64), types.UniTuple(types.float64, 2), types.none)
    assert listed(None, rates, elements) == (1.0, 2.0, 3.0)


def test_the_stability_bound_is_the_springs_against_the_booms_mass_with_a_stop_counted_within_reach():
    """Without spool lag, the valve closed and the stops' damping 0, the fastest mode is the
    springs against the boom's mass at the rod, sqrt(k / (J k^2)) with
    k = E (S1^2 / V1 + S2^2 / V2) + F_s / z_ba + k_spring, and the stop's k_stop added where the
    rod is within this step's reach of a stop (|v| dt + 0.1 mm), pressed into it or not; sliding
    faster, the seals' relaxation."""
    p = with_updates(P, spool_time_constant_s=0.0, spring_stiffness_n_m=3e4, end_stop_damping_n_s_m2=0.0)
    c = physical.constants(p)
    dt = p.time_step_s

    def expected(q1: float, stop: bool) -> float:
        vol1, vol2, _, _ = physical.chamber_volumes(q1, c)
        k = p.bulk_modulus_pa * (c.s1**2 / vol1 + c.s2**2 / vol2)
        k += p.static_friction_n / p.friction_presliding_m + p.spring_stiffness_n_m + stop * p.end_stop_stiffness_n_m
        return math.sqrt(k / (c.inertia * lever_rad_per_m(q1, p.a_m, p.b_m) ** 2))

    v = 2e-3  # slow: the seals' relaxation |v| / (z_ba r) stays below
    reach = v * dt + 1e-4
    lo, hi = p.cylinder_min_length_m, p.cylinder_max_length_m
    # (at exactly the reach's edge the stop is not yet within it)
    for q1, stop in [
        (1.2, False),
        (1.6, False),
        (lo + 0.9 * reach, True),
        (lo + 1.1 * reach, False),
        (lo + reach, False),
        (lo - 1e-3, True),
    ]:
        y = _state(p, q1, -v, 4e6, 1e6)
        assert physical.stiffness_rate(y, c, 0.0, dt) == pytest.approx(expected(q1, stop), rel=1e-12), q1
    for q1, stop in [(hi - 0.9 * reach, True), (hi - 1.1 * reach, False), (hi - reach, False), (hi + 1e-3, True)]:
        y = _state(p, q1, v, 4e6, 1e6)
        assert physical.stiffness_rate(y, c, 0.0, dt) == pytest.approx(expected(q1, stop), rel=1e-12), q1
    # sliding faster, the seals' relaxation |v| / (z_ba F_c / F_s) ("Friction") is the fastest
    for v in (0.05, -0.08):
        relaxation = abs(v) / (p.friction_presliding_m * p.coulomb_friction_n / p.static_friction_n)
        assert physical.stiffness_rate(_state(p, 1.6, v, 4e6, 1e6), c, 0.0, dt) == pytest.approx(relaxation, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# the accumulator (docs/model.md, "Accumulator", eq. A1-A6)


@pytest.mark.parametrize("position", ["piston", "supply"])
def test_the_accumulator_fills_through_its_orifice_from_its_own_line(position):
    """x' = Q / V0 (A2), Q the orifice's flow (A3) from the line it sits on (the piston chamber,
    or fixed_pump's supply line) into its gas at p0 (1 - x)^-n (A1), K = C_d A sqrt(2 / rho) of
    its orifice; the ledger books (p_line - p_gas) Q as its loss (A6) and (p_gas - p_tank) Q as
    the gas's power. The position is compared by value: a name built at run time (from a file)
    is the same position."""
    name = "".join(["pis", "ton"]) if position == "piston" else "".join(["sup", "ply"])
    drive = "pressure_compensated" if position == "piston" else "fixed_pump"
    p = with_updates(
        P, drive=drive, accumulator_gas_volume_m3=1e-3, accumulator_precharge_pa=3e5, accumulator_position=name
    )
    c = physical.constants(p)
    y = _state(p, 1.3, 0.02, 6e6, 1e6)
    fill = 0.35
    y[physical.ACCUMULATOR_STATE] = fill
    line = 6e6 if position == "piston" else drives.node_pressure(physical.drive_states(y), c)
    gas = p.accumulator_precharge_pa * (1.0 - fill) ** -p.accumulator_polytropic_exponent
    area = math.pi * p.accumulator_orifice_diameter_m**2 / 4.0
    k = p.discharge_coefficient * area * math.sqrt(2.0 / p.density_kg_m3)
    flow = accumulator.port_flow_m3_s(fill, line, gas, k, p.transition_pressure_pa**2)
    assert flow != 0.0
    rates = physical.derivative(0.0, y, c, 0.3)
    assert rates[physical.ACCUMULATOR_STATE] == pytest.approx(flow / 1e-3, rel=1e-9)
    terms = physical.ledger(0.0, y, c, 0.3)
    assert terms.accumulator_loss == pytest.approx((line - gas) * flow, rel=1e-9)
    assert terms.gas_power == pytest.approx((gas - p.tank_pressure_pa) * flow, rel=1e-9)
    # on the piston's line its flow leaves the chamber's: Q1 less it
    without = _out(y, c._replace(acc_on=0.0, acc_piston=0.0, acc_supply=0.0), 0.3)["q_in1"]
    taken = flow if position == "piston" else 0.0
    assert _out(y, c, 0.3)["q_in1"] == pytest.approx(without - taken, rel=1e-9)


def test_with_an_accumulator_the_bound_is_its_orifice_between_the_gas_and_the_lines_oil_springs():
    """Where it is the fastest mode, the bound is the accumulator's orifice's laminar slope
    K / sqrt(p_tr) times the gas spring and its line's oil spring in series (E / V1 on the piston
    chamber, E / V_s on fixed_pump's supply line; accumulator.fastest_rate_1_s), plus the rate at
    which the line's other paths drain its oil (E / V1 G_valve, none where a hose takes the valve's
    flow to its port node; the supply line's own rate)."""
    cases = [("piston", "pressure_compensated", 0.0), ("supply", "fixed_pump", 0.0)]
    for position, drive, hose_m in [*cases, ("piston", "pressure_compensated", 0.5)]:  # (0.5 m: a hose)
        p = with_updates(
            P,
            drive=drive,
            hose_length_m=hose_m,
            accumulator_gas_volume_m3=1e-3,
            accumulator_precharge_pa=3e5,
            accumulator_position=position,
            accumulator_orifice_diameter_m=0.02,
        )
        c = physical.constants(p)
        y = list(physical.initial_state(p))
        fill = y[physical.ACCUMULATOR_STATE]
        k = p.discharge_coefficient * math.pi * 0.02**2 / 4.0 * math.sqrt(2.0 / p.density_kg_m3)
        vol1 = physical.chamber_volumes(y[0], c)[0]
        line = p.bulk_modulus_pa / (vol1 if position == "piston" else c.line_volume)
        rate = accumulator.fastest_rate_1_s(
            fill, 3e5, p.accumulator_polytropic_exponent, 1e-3, line, k / math.sqrt(p.transition_pressure_pa)
        )
        stiff1, stiff2 = (p.bulk_modulus_pa / v for v in physical.chamber_volumes(y[0], c)[:2])
        z = physical.drive_states(y)
        g_a, _, own = drives.stiffness(z, 0.0, 0.0, stiff1, stiff2, p.time_step_s, c, math, 1e300)
        rate += (stiff1 * g_a if hose_m == 0.0 else 0.0) if position == "piston" else own
        assert physical.stiffness_rate(y, c, 0.0, p.time_step_s) == pytest.approx(rate, rel=1e-12), position
        if position == "piston" and hose_m == 0.0:  # within reach of its relief, that drains the chamber too
            y[2] = p.relief_pressure_pa + 1e5
            rate += stiff1 * p.relief_rated_flow_m3_s / p.relief_range_pa
            assert physical.stiffness_rate(y, c, 0.0, p.time_step_s) == pytest.approx(rate, rel=1e-12)


def test_the_stored_energy_holds_each_hoses_own_nodes_and_flows():
    """H holds each hose's line energy (eq. H6) of its own four node states and four flows:
    marked states (every node and flow its own value) change H by the lines' energies."""
    p = CRANE
    c = physical.constants(p)
    y = list(physical.initial_state(p))
    rng = np.random.default_rng(11)
    lines = []
    for first in (physical.HOSE_STATE, physical.HOSE_STATE + hoses.LINE_B):
        z = tuple(rng.uniform(2e6, 9e6, hoses.SEGMENTS))
        q = tuple(rng.uniform(-4e-4, 4e-4, hoses.SEGMENTS))
        y[first : first + 2 * hoses.SEGMENTS] = [*z, *q]
        lines.append(hoses.line_energy(z, q, c, p.cavitation_pressure_pa, p.tank_pressure_pa))
    without = physical.energy(y, c._replace(hose_on=0.0))
    assert physical.energy(y, c) - without == pytest.approx(sum(lines), rel=1e-9)


def test_with_hoses_the_valve_feeds_the_hoses_port_nodes_and_a_chamber_near_its_relief_adds_it():
    """With hoses the drive holds each line at the hose's port node (half a segment's oil,
    hoses.port_stiffness): the chamber's rate is E_port G (G = dQ/dp the drive's, drives.stiffness),
    and a chamber that can reach its relief within the step adds its own E / V G_relief; the other
    chamber, far from its relief, does not."""
    p = CRANE
    c = physical.constants(p)
    u, q1 = 1.0, 1.8
    port = hoses.port_stiffness(c)
    for near in (0, 1):  # the piston chamber near its relief, then the rod chamber
        pressures = [2e6, 2e6]
        pressures[near] = p.relief_pressure_pa + 1e5
        y = _state(p, q1, 0.0, *pressures, spool=u)
        g = drives.stiffness(physical.drive_states(y), u, u, port, port, p.time_step_s, c, math, 1e300)
        vol = physical.chamber_volumes(q1, c)[near]
        relief = p.bulk_modulus_pa / vol * p.relief_rated_flow_m3_s / p.relief_range_pa
        bound = physical.stiffness_rate(y, c, u, p.time_step_s)
        assert bound == pytest.approx(port * g[near] + relief, rel=1e-9)
        assert bound > port * g[1 - near]


def test_the_state_layout_names_each_index_the_model_reads():
    """The indices the stepping, the ledger and the outputs read are those of the states named so
    (STATE_NAMES), one scale per state, the model elements' last (BASE_SIZE before them)."""
    names = physical.STATE_NAMES
    assert len(physical.STATE_SCALES) == len(names) == len(set(names))
    assert physical.ENERGY_STATES == (names.index("energy_change"), names.index("energy_change_abs"))
    assert physical.DRIVE_STATES == tuple(names.index(n) for n in ("drive_state", "drive_state_2", "drive_state_3"))
    assert physical.DRIVE_STATE == physical.DRIVE_STATES[0]
    assert physical.LEDGER_STATES == names.index(INTEGRALS[0]) and physical.LIFT_WORK == names.index("lift_work")
    assert physical.BATTERY_DRAWN == names.index("battery_drawn") and physical.BATTERY_RETURNED == names.index(
        "battery_returned"
    )
    assert physical.ACCUMULATOR_STATE == names.index("accumulator_fill") == physical.BASE_SIZE
    assert physical.HOSE_STATES == tuple(names.index(n) for n in hoses.STATE_NAMES)
    assert physical.BOOM_STATES == (names.index("boom_deflection"), names.index("boom_deflection_rate"))
    assert physical.BASE_SIZE + 1 + len(hoses.STATE_NAMES) + 2 == len(names)
    assert physical.ELEMENT_UNITS == {
        physical.ACCUMULATOR_STATE: "1",
        **dict(zip(physical.HOSE_STATES, hoses.STATE_UNITS)),
        names.index("boom_deflection"): "m",
        names.index("boom_deflection_rate"): "m/s",
    }


def test_with_hoses_the_drive_sees_its_ports_pressures_the_hoses_first_nodes():
    """With hoses the drive feeds the hoses' first nodes and sees their pressures, not the
    chambers' (eq. H4): its supply power is that of the same drive without hoses whose chambers
    stand at those nodes' pressures."""
    p = CRANE
    c = physical.constants(p)
    y = _state(p, 1.8, 0.03, 9.0e6, 1.5e6, spool=0.6)
    port_a, port_b = 7.5e6, 2.5e6
    y[physical.HOSE_STATE], y[physical.HOSE_STATE + hoses.LINE_B] = port_a, port_b
    bare = c._replace(hose_on=0.0)
    at_ports = [*y[:2], port_a, port_b, *y[4:]]
    assert _out(y, c, 0.6)["power"] == pytest.approx(_out(at_ports, bare, 0.6)["power"], rel=1e-12)
    assert _out(y, c, 0.6)["power"] != _out(y, bare, 0.6)["power"]


def test_physical_mode_steps_in_the_substeps_its_bound_asks_for_and_paper_mode_at_the_users_step():
    """The run loop takes substeps so that dt times stiffness_rate stays within the method's
    stability limit in physical mode (STABILITY_BOUND) and none in paper mode ("Stepping")."""
    from boom_hydraulics.solve import batch, integrators

    assert batch.stability_limit(P) == integrators.METHODS[P.method].stability_limit > 0.0
    assert batch.stability_limit(with_updates(P, mode="paper")) == 0.0
