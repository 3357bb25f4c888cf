"""The variable pump that delivers on demand (model/drives/pressure_compensated.py, shared by
load_sensing) with its motor at speed on demand, at known operating points: the speed it
heads for (eq. D62), the pressure a slow pump can hold (eq. D19 at D w, the dead-heading
eq. D62), the stroke that delivers the valve's flow and leakage (eq. D4) and the torque its
rotors ask (eq. D64). docs/model.md, "Drives" and "Motor strategies"."""

from __future__ import annotations

import numpy as np
import pytest

from boom_hydraulics.model import pump, valve
from boom_hydraulics.model.drives import DRIVES, constants, load_sensing, motor_speed, pressure_compensated
from boom_hydraulics.model.parameters import Parameters, with_updates

P = Parameters()
D = constants(P)
#: speed on demand without a lag (the speed is its target at once) and with the default 50 ms
ON_DEMAND = constants(with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.0))
LAGGING = constants(with_updates(P, motor_strategy="speed_on_demand"))
#: a valve whose wide open path takes more than Q_max at 0.43 MPa (test_drives' too)
WIDE = constants(with_updates(P, orifice_diameter_m=0.006))
WIDE_LAGGING = constants(with_updates(P, orifice_diameter_m=0.006, motor_strategy="speed_on_demand"))
P_N, P_T = P.supply_pressure_pa, P.tank_pressure_pa


def _stroke(s, d=D) -> float:
    """The pump's stroke (displacement, m^3/rad) from its torque: T is linear in D (eq. D2)."""
    return (s.torque - d.rotor_inertia * s.rate2 * d.motor_lag) / pump.shaft_torque_n_m(
        1.0, s.speed, s.p_supply - d.p_tank, d.torque_loss
    )


def test_a_slow_pump_holds_at_most_its_dead_heading_pressure_and_a_stopped_one_none():
    """With the spool closed, the P port sees p_n, or p_t + D w / G_p where the pump's flow at
    speed w cannot make up its own leakage at p_n (eq. D62); a stopped pump holds (next to) none."""
    dead_head = lambda w: P_T + D.displacement * w / D.pump_leak  # noqa: E731
    assert dead_head(1.0) < P_N < dead_head(P.pump_speed_rad_s)
    at = pressure_compensated.port_pressure_at_speed_pa
    assert at(P_N, 1.0, 0.0, 6e6, 1e5, D) == pytest.approx(dead_head(1.0), rel=1e-12)
    assert at(P_N, P.pump_speed_rad_s, 0.0, 6e6, 1e5, D) == P_N
    assert P_T <= at(P_N, 0.0, 0.0, 6e6, 1e5, D) < P_T + 10.0  # D x 1e-6 rad/s over G_p: a few Pa
    assert at(P_N, -5.0, 0.0, 6e6, 1e5, D) == at(P_N, 0.0, 0.0, 6e6, 1e5, D)
    # opened wide, the flow limit of the pump at w_n is Q_max's, as port_pressure_pa's
    wide = pressure_compensated.port_pressure_pa(P_N, 1.0, 6e6, 1e5, WIDE)
    assert wide < P_N and at(P_N, P.pump_speed_rad_s, 1.0, 6e6, 1e5, WIDE) == pytest.approx(wide, rel=1e-12)
    assert 6e6 < at(P_N, 0.5 * P.pump_speed_rad_s, 1.0, 6e6, 1e5, WIDE) < wide  # half the flow: less drop


@pytest.mark.parametrize(
    ("opening", "p1_pa"), [(0.05, 6e6), (0.3, 6e6), (-0.2, 3e6), (0.0, 6e6), (0.6, 6e6), (1.0, 9e6)]
)  # w_min for the first four, between w_min and w_n for the last two
def test_speed_on_demand_turns_the_pump_at_the_speed_that_delivers_the_valves_flow_and_leakage(opening, p1_pa):
    """eq. D62: w = (Q_P + G_p dp) / D between w_min and w_n, Q_P what the valve's P paths take
    at the P port's pressure of the pump at full flow; at that speed the stroke delivers what
    the valve takes at the port's pressure at speed (eq. D4), and the drive books dp Q_P."""
    z = (P_N, 0.0, 0.0)
    s = pressure_compensated.supply(z, opening, opening, 1.4, 0.0, p1_pa, 1e5, ON_DEMAND)
    ps0 = pressure_compensated.port_pressure_pa(P_N, opening, p1_pa, 1e5, ON_DEMAND)
    wanted = valve.paths(opening, ps0, p1_pa, 1e5, ON_DEMAND).q_in + D.pump_leak * (ps0 - P_T)
    speed = min(max(wanted / D.displacement, P.motor_min_speed_rad_s), P.pump_speed_rad_s)
    assert s.speed == pytest.approx(speed, rel=1e-12)
    ps = pressure_compensated.port_pressure_at_speed_pa(P_N, speed, opening, p1_pa, 1e5, ON_DEMAND)
    assert s.p_supply == pytest.approx(ps, rel=1e-12)
    q_in = valve.paths(opening, s.p_supply, p1_pa, 1e5, ON_DEMAND).q_in
    dp = s.p_supply - P_T
    assert s.power == pytest.approx(dp * q_in, rel=1e-12) and s.hydraulic_power == pytest.approx(s.power, rel=1e-12)
    assert _stroke(s) * s.speed == pytest.approx(q_in + D.pump_leak * dp, rel=1e-9)  # eq. D4
    assert (s.rate, s.rate2, s.rate3, s.rotor_power) == (0.0, 0.0, 0.0, 0.0)  # no lag: nothing to store


def test_a_lagging_motor_asks_its_rotors_torque_beside_the_pumps_and_stores_their_energy():
    """At 80 rad/s heading for w_n (a wide spool wide open asks more than Q_max): w' = (w_n - 80) / tau,
    the P port at the flow limit of 80 rad/s, the shaft torque
    the pump's plus J w', the rotors' power J w w' (eq. D63, D64), and energy_rate is the rate of
    the drive's energy J w^2 / 2."""
    z = (P_N, 80.0, 0.0)
    s = pressure_compensated.supply(z, 1.0, 1.0, 1.4, 0.0, 6e6, 1e5, WIDE_LAGGING)
    tau, inertia = P.motor_time_constant_s, P.motor_rotor_inertia_kg_m2
    assert s.speed == 80.0 and s.rate2 == pytest.approx((P.pump_speed_rad_s - 80.0) / tau, rel=1e-12)
    assert s.rotor_power == pytest.approx(inertia * 80.0 * s.rate2, rel=1e-12)
    q_in = valve.paths(1.0, s.p_supply, 6e6, 1e5, WIDE_LAGGING).q_in
    stroke = (q_in + D.pump_leak * (s.p_supply - P_T)) / 80.0
    pump_torque = pump.shaft_torque_n_m(stroke, 80.0, s.p_supply - P_T, D.torque_loss)
    assert s.torque == pytest.approx(pump_torque + inertia * s.rate2, rel=1e-12)
    assert s.saturated == 1.0 and s.p_supply < pressure_compensated.port_pressure_pa(P_N, 1.0, 6e6, 1e5, WIDE)
    assert q_in == pytest.approx(D.displacement * 80.0, rel=5e-3)  # D w through the path (eq. D19: leakage neglected)
    assert pressure_compensated.energy(z, LAGGING) == pytest.approx(0.5 * inertia * 80.0**2, rel=1e-12)
    assert pressure_compensated.energy_rate(z, s, LAGGING) == pytest.approx(s.rotor_power, rel=1e-12)


def test_the_drive_starts_at_p_n_with_its_motors_states_and_its_fastest_rate_is_the_motors():
    assert pressure_compensated.initial_state(D) == (P_N, 0.0, 0.0)
    assert pressure_compensated.initial_state(LAGGING) == (P_N, P.motor_min_speed_rad_s, 0.0)
    slope = valve.laminar_slope(0.3, D)
    assert pressure_compensated.stiffness((P_N, 0.0, 0.0), 0.3, 0.3, 1e-3, 1e-3, 1e-3, D) == (slope, slope, 0.0)
    rate = pressure_compensated.stiffness((P_N, 0.0, 0.0), 0.3, 0.3, 1e-3, 1e-3, 1e-3, LAGGING)[2]
    assert rate == motor_speed.fastest_rate(LAGGING) == 1.0 / P.motor_time_constant_s
    tight = D._replace(leak=0.0)  # a valve that leaks nothing, closed: no slope, no rate at constant speed
    assert pressure_compensated.stiffness((P_N, 0.0, 0.0), 0.0, 0.0, 1e-3, 1e-3, 1e-3, tight) == (0.0, 0.0, 0.0)


def test_load_sensing_starts_at_its_margin_and_its_fastest_rate_is_its_pumps_lag_or_its_motors():
    """The pump idles at p_t + margin; the step's fastest rate is 1 / tau_LS, or the motor's
    1 / tau_m where that is faster."""
    assert load_sensing.initial_state(D) == (P_T + P.load_sensing_margin_pa, 0.0, 0.0)
    z = (5e6, 0.0, 0.0)
    assert load_sensing.stiffness(z, 0.3, 0.3, 1e-3, 1e-3, 1e-3, D)[2] == 1.0 / P.load_sensing_time_constant_s
    quick = constants(with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.001))
    assert load_sensing.stiffness(z, 0.3, 0.3, 1e-3, 1e-3, 1e-3, quick)[2] == pytest.approx(1000.0, rel=1e-12)
    tight = D._replace(leak=0.0)  # a valve that leaks nothing, closed: its laminar slope is 0
    assert load_sensing.stiffness(z, 0.0, 0.0, 1e-3, 1e-3, 1e-3, tight) == (0.0, 0.0, D.ls_inv_tau)


def test_a_drive_is_steady_exactly_where_its_states_stand_still():
    """STEADY_SUPPLY (a linear model leaves the drive's states out) holds for the drive whose
    states' rates are 0 at the default constant speed, and only for it: load sensing's pump
    pressure, the fixed pump's line, the motors of the EHA and the actuator move."""
    moving = set()
    for name, module in DRIVES.items():
        d = constants(with_updates(P, drive=name))
        s = module.supply(module.initial_state(d), 0.3, 0.3, 1.4, 0.05, 6e6, 1e5, d)
        if (s.rate, s.rate2, s.rate3) != (0.0, 0.0, 0.0):
            moving.add(name)
        assert module.STEADY_SUPPLY == (name not in moving), name
    assert moving == set(DRIVES) - {"pressure_compensated"}


def test_a_valve_drive_reports_the_spool_position_its_paths_see_and_moves_the_rod_through_the_oil():
    """Supply.spool is the x_v output: the valve drives give the spool's position, either way;
    the chambers' pressures push the rod (cylinder 1) and the drive puts no force of its own on it."""
    for name, module in DRIVES.items():
        if module.VALVE:
            d = constants(with_updates(P, drive=name))
            for opening in (0.37, -0.61):
                s = module.supply(module.initial_state(d), 0.9, opening, 1.4, 0.0, 6e6, 1e5, d)
                assert (s.spool, s.cylinder, s.force) == (opening, 1.0, 0.0), name


def _batch(*sets):
    """The drives' constants of several sets as one batch (numpy arrays, a value per set)."""
    return type(sets[0])(*(np.array([float(getattr(s, f)) for s in sets]) for f in sets[0]._fields))


@pytest.mark.parametrize("name", ["pressure_compensated", "load_sensing", "fixed_pump"])
def test_a_batch_of_sets_with_different_motor_strategies_gives_each_set_what_it_gives_alone(name):
    """A sweep's block of sets mixes the motor's strategies: each set's Supply is its own run's
    (the constant motor's P port is not the variable motor's, nor the other way round)."""
    module = DRIVES[name]
    sets = [
        constants(with_updates(P, drive=name)),
        constants(with_updates(P, drive=name, motor_strategy="speed_on_demand")),
        constants(with_updates(P, drive=name, motor_strategy="idle_stop")),
    ]
    states = [(1.2e7, 0.0, 0.0), (1.2e7, 90.0, 0.0), (1.2e7, 120.0, 0.4)]
    batch = module.supply(tuple(np.array(z) for z in zip(*states)), 0.4, 0.4, 1.4, 0.02, 6e6, 1e5, _batch(*sets), np)
    for k, (d, z) in enumerate(zip(sets, states)):
        alone = module.supply(z, 0.4, 0.4, 1.4, 0.02, 6e6, 1e5, d)
        for field, value in zip(alone._fields, alone):
            assert batch._asdict()[field][k] == pytest.approx(value, rel=1e-12, abs=1e-12), (name, k, field)
