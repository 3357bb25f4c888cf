"""Physical mode: conservation laws, an independent formulation, and the circuit's behaviour."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from boom_hydraulics.model import geometry, hydraulics, mechanics, physical
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import integrators
from boom_hydraulics.solve.commands import steps
from boom_hydraulics.solve.simulation import Simulator, simulate

P = Parameters()
J = mechanics.boom_inertia_kgm2(P.boom_mass_kg, P.payload_mass_kg, P.boom_length_m)
W = (0.5 * P.boom_mass_kg + P.payload_mass_kg) * P.boom_length_m * P.gravity_m_s2  # M_g = W cos(alpha)


def _integrate(fun, y0, dt, n):
    ys = [y0]
    for i in range(n):
        ys.append(integrators.rk4_step(fun, i * dt, ys[-1], dt))
    return np.array(ys)


def _energy(q, v):
    k = geometry.lever_rad_per_m(q, P.a_m, P.b_m, np)
    alpha = geometry.boom_angle_rad(q, P.a_m, P.b_m, P.support_height_m, np)
    return 0.5 * J * (k * v) ** 2 + W * np.sin(alpha)  # T (eq. 8) + potential energy


def test_falling_boom_conserves_energy_without_hydraulics_and_friction():
    def fall(t, y):
        return [y[1], mechanics.rod_acceleration(y[0], y[1], 0.0, J, W, P.a_m, P.b_m, P.support_height_m)]

    ys = _integrate(fall, [1.6, 0.0], 1e-4, 4000)
    q, v = ys[:, 0], ys[:, 1]
    assert q[-1] < 1.5  # it really fell
    energy = _energy(q, v)
    kinetic_max = np.max(0.5 * J * (geometry.lever_rad_per_m(q, P.a_m, P.b_m, np) * v) ** 2)
    assert np.max(np.abs(energy - energy[0])) < 1e-6 * kinetic_max


def test_the_paper_acceleration_does_not_conserve_energy():
    """The factor 1/2 of eq. 16 shows up as lost energy (why physical mode corrects it)."""

    def fall(t, y):
        return [y[1], mechanics.paper_acceleration(y[0], y[1], 0.0, 0.0, 0.0, J, W, P.a_m, P.b_m, P.support_height_m)]

    ys = _integrate(fall, [1.6, 0.0], 1e-4, 4000)
    energy = _energy(ys[:, 0], ys[:, 1])
    assert abs(energy[-1] - energy[0]) > 0.1 * abs(np.max(energy) - np.min(energy))


def test_q1_formulation_agrees_with_a_pendulum_in_alpha():
    """J alpha'' = F / k - M_g in alpha, mapped to q1, gives the same motion."""
    force = 6000.0
    alpha2 = math.acos(P.support_height_m / P.b_m)

    def in_q(t, y):
        return [y[1], mechanics.rod_acceleration(y[0], y[1], force, J, W, P.a_m, P.b_m, P.support_height_m)]

    def q_of_alpha(alpha):
        theta = alpha + math.pi / 2 - alpha2  # eq. 4 solved for theta
        return math.sqrt(P.a_m**2 + P.b_m**2 - 2 * P.a_m * P.b_m * math.cos(theta))

    def in_alpha(t, y):
        q = q_of_alpha(y[0])
        k = geometry.lever_rad_per_m(q, P.a_m, P.b_m)
        return [y[1], (force / k - W * math.cos(y[0])) / J]

    q0 = 1.3
    alpha0 = geometry.boom_angle_rad(q0, P.a_m, P.b_m, P.support_height_m)
    by_q = _integrate(in_q, [q0, 0.0], 1e-4, 10000)[:, 0]
    by_alpha = np.array([q_of_alpha(a) for a in _integrate(in_alpha, [alpha0, 0.0], 1e-4, 10000)[:, 0]])
    assert by_q[-1] - q0 > 0.1  # the rod force lifts the boom
    assert np.max(np.abs(by_q - by_alpha)) < 1e-9


def test_closed_valve_at_holding_pressure_holds_the_boom():
    tr = simulate(P, 2.0, command=lambda t: 0.0)
    assert np.max(np.abs(tr["q1"] - P.initial_length_m)) < 1e-3  # leakage drift only
    assert abs(tr["v"][-1]) < 1e-3


@pytest.mark.parametrize("external_n", [2000.0, -5000.0])
def test_an_external_rod_force_takes_its_share_off_the_holding_pressure(external_n):
    """Eq. 11 at rest with the valve closed: F_ext (positive extending) carries F_ext of the
    boom's static force, so the piston chamber holds it at F_ext / S1 less pressure; the model's
    own acceleration there is zero, and with the force held the boom stays where it is."""
    p = with_updates(P, external_rod_force_n=external_n)
    s1 = geometry.piston_area_m2(P.piston_diameter_m)
    y0, y = physical.initial_state(P), physical.initial_state(p)
    assert y0[2] - y[2] == pytest.approx(external_n / s1, rel=1e-12)  # 1.59 MPa per 2 kN on 40 mm (load: 4.9 kN)
    c = physical.constants(p)
    k = geometry.lever_rad_per_m(y[0], c.a, c.b)
    acc = physical.derivative(0.0, y, c, 0.0)[1]
    assert abs(acc) * c.inertia * k * k < 1e-6  # N at the rod: an equilibrium of the model
    off = physical.derivative(0.0, y0, c, 0.0)[1] * c.inertia * k * k  # the old state is none
    assert off == pytest.approx(external_n, rel=1e-9)
    tr = simulate(p, 2.0, command=lambda t: 0.0)
    assert np.max(np.abs(tr["q1"] - P.initial_length_m)) < 1e-3  # leakage drift only, as without it


def test_fluid_entering_a_chamber_equals_the_integral_of_its_flow():
    """For eq. 12: integral of Q1 dt = change of V1 + integral of V1 / E dp1."""
    params = with_updates(P, time_step_s=2e-4)
    tr = simulate(params, 2.0, command=steps([0.0, 1.0], [0.5, -0.3]))
    assert not tr["cavitation"].any() and not tr["relief_open"].any()
    t, p1 = tr["t"], tr["p1"]
    vol1 = P.piston_dead_volume_m3 + physical.constants(P).s1 * (tr["q1"] - P.cylinder_min_length_m)
    inflow = np.trapezoid(tr["q_in1"], t)
    stored = vol1[-1] - vol1[0] + np.trapezoid(vol1 / P.bulk_modulus_pa * np.gradient(p1, t), t)
    assert abs(inflow) > 2e-5  # fluid did move
    assert inflow == pytest.approx(stored, rel=2e-3)


def test_end_stops_hold_the_rod_within_their_compliance():
    """Full-speed impacts with the pump pushing: the 1e8 N/m stops give about 2 mm."""
    tr = simulate(P, 9.0, command=steps([0.0, 4.0], [1.0, -1.0]), every=5)
    q = tr["q1"]
    assert q.max() > P.cylinder_max_length_m - 1e-3 and q.min() < P.cylinder_min_length_m + 1e-3  # reached both
    assert q.max() < P.cylinder_max_length_m + 2.5e-3 and q.min() > P.cylinder_min_length_m - 2.5e-3
    assert tr["at_end_stop"].any()


def test_pressures_stay_between_cavitation_floor_and_relief_range():
    """Slamming the valve shut at full speed (no spool lag) opens a relief valve."""
    params = with_updates(P, spool_time_constant_s=0.0, time_step_s=2e-4)
    tr = simulate(params, 4.0, command=steps([0.0, 1.0, 2.0, 2.8], [1.0, 0.0, -1.0, 0.0]))
    assert tr["relief_open"].any()
    for p in (tr["p1"], tr["p2"]):
        assert p.max() <= P.relief_pressure_pa + P.relief_range_pa
        assert p.min() >= P.cavitation_pressure_pa


def test_lowering_an_overrunning_load_cavitates_the_rod_chamber():
    """A heavy payload lowered with the valve wide open outruns the pump: flagged cavitation."""
    params = with_updates(P, payload_mass_kg=400.0, pump_max_flow_m3_s=1e-4)
    tr = simulate(params, 1.0, command=lambda t: -1.0)
    assert tr["cavitation"].any()
    assert tr["p2"].min() == pytest.approx(P.cavitation_pressure_pa)


def _steady_speed(params: Parameters, q1: float) -> float:
    """Rod speed at which both orifices pass the flow the piston needs against the static load."""
    c = physical.constants(params)
    load = geometry.static_rod_force_of(params, q1)

    def residual(v):
        p1 = params.supply_pressure_pa - hydraulics.orifice_pressure_drop(c.k_valve, c.s1 * v, c.transition2)
        p2 = params.tank_pressure_pa + hydraulics.orifice_pressure_drop(c.k_valve, c.s2 * v, c.transition2)
        friction = params.coulomb_friction_n + params.viscous_friction_n_s_m * v
        return p1 * c.s1 - p2 * c.s2 - load - friction

    return brentq(residual, 1e-6, 2.0)


def test_steady_extension_speed_matches_the_orifice_equation_at_the_load():
    tr = simulate(P, 1.5, command=lambda t: 1.0)
    i = int(np.argmin(np.abs(tr["q1"] - 1.5)))
    assert tr["v"][i] == pytest.approx(_steady_speed(P, tr["q1"][i]), rel=0.01)


def test_pump_flow_limit_caps_the_speed():
    params = with_updates(P, pump_max_flow_m3_s=1e-4)
    tr = simulate(params, 2.0, command=lambda t: 1.0)
    window = (tr["t"] >= 0.5) & (tr["t"] <= 1.5)
    assert tr["pump_saturated"][window].all()
    # a flow source against the oil spring rings, so compare the mean speed over a second
    mean_speed = (tr["q1"][window][-1] - tr["q1"][window][0]) / 1.0
    assert mean_speed == pytest.approx(1e-4 / physical.constants(params).s1, rel=0.01)


def test_reset_returns_to_rest_at_a_given_position():
    sim = Simulator(P)
    sim.step(1.0, 500)
    sim.reset(1.6)
    assert sim.y[0] == 1.6 and sim.y[1] == 0.0 and sim.t == 0.0
    sim.step(0.0, 300)
    assert abs(sim.y[0] - 1.6) < 1e-3


def test_the_orifice_law_through_the_models_constants():
    """Q = K dp / (dp^2 + p_tr^2)^(1/4), with K = mu (pi D_dr^2 / 4) sqrt(2 / rho) written out
    here: laminar slope K / sqrt(p_tr) at equal pressures, turbulent K sqrt(dp) far from them."""
    params = Parameters()
    c = physical.constants(params)
    k = params.discharge_coefficient * math.pi * params.orifice_diameter_m**2 / 4 * math.sqrt(2 / params.density_kg_m3)
    p_tr = params.transition_pressure_pa
    tank, supply = params.tank_pressure_pa, params.supply_pressure_pa

    def piston_inflow(p1: float) -> float:  # valve fully open P->A, no leakage
        q_pa, _, _, _ = hydraulics.valve_flows(1.0, supply, tank, p1, tank, c.k_valve, c.transition2, 0.0)
        return q_pa

    dp = 10.0  # Pa: deep in the laminar region
    assert piston_inflow(supply - dp) / dp == pytest.approx(k / math.sqrt(p_tr), rel=1e-6)
    far = 15e6  # Pa: 50 times the transition pressure
    assert piston_inflow(supply - far) == pytest.approx(k * math.sqrt(far), rel=2e-4)
    assert piston_inflow(supply) == 0.0 and piston_inflow(supply + dp) < 0  # flow turns with the drop


def _cycle(payload_kg: float, external_n: float = 0.0) -> dict:
    """A 9 s lift-hold-lower-hold cycle at 1 ms, with every energy flow of the drive integrated
    beside the model (trapezoid over each step, the step's command held)."""
    p = with_updates(Parameters(), payload_mass_kg=payload_kg, external_rod_force_n=external_n)
    c = physical.constants(p)
    command = steps([0.0, 3.0, 4.0, 7.0], [1.0, 0.0, -1.0, 0.0])

    def mechanical(y):  # kinetic + potential (boom and payload) + spring energy, J
        k = geometry.lever_rad_per_m(y[0], c.a, c.b)
        height = math.sin(geometry.boom_angle_rad(y[0], c.a, c.b, c.h))
        return (
            0.5 * c.inertia * (k * y[1]) ** 2 + c.weight_coeff * height + 0.5 * c.spring * (y[0] - c.spring_free) ** 2
        )

    def powers(y, u):  # friction, end stop, ambient-minus-tank pressure on the rod area, chambers, F_ext; W
        t = physical._terms(list(y), c, u, math)
        chambers = (t.p1 - c.p_tank) * (t.q_in1 - c.s1 * y[1]) + (t.p2 - c.p_tank) * (t.q_in2 + c.s2 * y[1])
        rod = (c.p_ambient - c.p_tank) * (c.s1 - c.s2) * y[1]
        return np.array([t.f_friction * y[1], t.f_stop * y[1], rod, chambers, external_n * y[1]])

    sim = Simulator(p)
    start, work = mechanical(sim.y), np.zeros(5)
    q1, pressure, cavitation, relief = [], [], 0, 0
    for _ in range(9000):
        u = command(sim.t + 0.5e-3)
        before = powers(sim.y, u)
        sim.step(u)
        work += 0.5 * (before + powers(sim.y, u)) * 1e-3
        out = sim.outputs()
        q1.append(out["q1"])
        pressure.append(max(out["p1"], out["p2"]))
        cavitation += bool(out["cavitation"])
        relief += bool(out["relief_open"])
    friction, stop, rod, chambers, external = work
    return {
        "supply": sim.y[5],
        "accounted": sim.y[6] + mechanical(sim.y) - start + friction - stop - rod + chambers - external,
        "external_work": external,
        "stop_work": stop,
        "overshoot_m": max(max(q1) - c.q_max, c.q_min - min(q1)),
        "peak_pa": max(pressure),
        "cavitation_steps": cavitation,
        "relief_steps": relief,
    }


@pytest.mark.parametrize(("payload_kg", "external_n"), [(0.0, 0.0), (150.0, 0.0), (50.0, -3000.0)])
def test_the_energy_of_a_cycle_balances_through_relief_and_cavitation(payload_kg, external_n):
    """Supply energy = valve and relief losses + change of kinetic and potential energy +
    friction + end-stop work + the work of ambient minus tank pressure on the rod area + what
    the chambers took in (compression, and the void while cavitating) - the work the external
    rod force did on the rod (F_ext v), each integrated beside the model (the requirement is 1 %)."""
    cycle = _cycle(payload_kg, external_n)
    assert (abs(cycle["external_work"]) > 0.05 * cycle["supply"]) == (external_n != 0.0)  # a term that counts
    assert cycle["cavitation_steps"] > 0  # the events the balance has to hold through
    assert cycle["relief_steps"] > 0 or payload_kg > 0
    assert abs(cycle["supply"] - cycle["accounted"]) < 0.005 * cycle["supply"]


def test_end_stops_dissipate_energy_and_hold_the_rod():
    """Both stops are hit in the 150 kg cycle: their force takes energy out, never puts it in;
    the rod presses less than 2.5 mm into them (their stiffness is 1e8 N/m) and the pressure
    stays under 19 MPa (the port relief valves crack at 18 MPa)."""
    cycle = _cycle(150.0)
    assert cycle["stop_work"] < -100.0  # J dissipated over two impacts and the pressing
    assert cycle["overshoot_m"] < 2.5e-3
    assert cycle["peak_pa"] < 19e6


def test_a_cavitating_chamber_holds_at_its_floor_for_as_long_as_the_load_overruns():
    """Valve closed, the boom moving down at 0.2 m/s: the sealed rod chamber expands, falls to
    the cavitation floor and is held there, not below, until the rod stops. The rod stops on
    the oil spring of the piston chamber; independently, with the effective mass J k^2, the
    stiffness E S1^2 / V1 and the force the rod chamber lost, v = v0 cos(wt) + F0/(m w) sin(wt)
    is zero after atan(|v0| m w / F0) / w (friction left out: a few percent)."""
    params = with_updates(Parameters(), initial_velocity_m_s=-0.2, time_step_s=1e-4, load_holding_valve="none")
    c = physical.constants(params)
    sim = Simulator(params)
    q0, p2_0 = sim.y[0], sim.y[3]
    at_floor, lowest = 0, math.inf
    while sim.y[1] < 0.0:  # until the rod stops
        sim.step(0.0)
        out = sim.outputs()
        lowest = min(lowest, out["p2"])
        if out["void2"] > 0.0:
            at_floor += 1
            assert out["p2"] == c.p_cav and out["cavitation"]  # a void stands at the floor pressure
        assert sim.t < 1.0
    assert lowest == c.p_cav  # held at the floor, never below
    k = geometry.lever_rad_per_m(q0, c.a, c.b)
    m = c.inertia * k * k
    w = math.sqrt(c.bulk_modulus * c.s1**2 / (c.v1_dead + c.s1 * (q0 - c.q_min)) / m)
    f0 = (p2_0 - c.p_cav) * c.s2
    estimate_s = math.atan(0.2 * m * w / f0) / w
    assert at_floor * 1e-4 == pytest.approx(estimate_s, rel=0.05)
