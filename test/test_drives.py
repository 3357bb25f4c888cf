"""The drives' elements against analytic cases: relief, fixed pump, load sensing, EHA, pump, motor, battery."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from boom_hydraulics.errors import ConfigError
from boom_hydraulics.model import battery, config, electric_motor, geometry, hydraulics, pump, valve
from boom_hydraulics.model.drives import (
    DRIVES,
    STATE_COUNT,
    constants,
    fixed_pump,
    holds_oil,
    load_sensing,
    pump_controlled,
)
from boom_hydraulics.model.drives.constants import Supply, blend, chosen, in_use
from boom_hydraulics.model.ledger import electric_chain
from boom_hydraulics.model.parameters import DRIVES as DRIVE_CHOICES
from boom_hydraulics.model.parameters import UNSOLVED, Parameters, describe, from_mapping, with_updates

P = Parameters()
D = constants(P)


# --- the parameter and the registry ----------------------------------------------------


def test_one_registry_of_drives_behind_one_start_only_parameter_defaulting_to_todays_source():
    assert tuple(DRIVES) == DRIVE_CHOICES == describe("drive")["choices"]
    assert P.drive == "pressure_compensated" and describe("drive")["start_only"]
    assert describe("drive")["group"] == "plant"
    for name, module in DRIVES.items():
        assert 1 <= len(module.STATE_NAMES) == len(module.STATE_SCALES) <= STATE_COUNT, name
        for function in ("initial_state", "supply", "energy", "energy_rate", "stiffness"):
            assert callable(getattr(module, function)), (name, function)
        assert len(module.initial_state(D)) == STATE_COUNT, name
    assert not pump_controlled.VALVE and callable(pump_controlled.ports)


@pytest.mark.parametrize("drive", DRIVE_CHOICES)
def test_a_valve_drive_feeds_the_lines_through_the_spool_and_the_eha_by_its_command(drive):
    """VALVE: the spool, not the command, lets the pump's oil into the lines (closed, only
    the valve's leakage passes); a drive without the valve feeds them whatever the spool: the
    EHA's pump at its speed, the actuator's housing (no oil) only as the rod breathes."""
    module = DRIVES[drive]
    z = (P.supply_pressure_pa, 0.0, 0.0) if module.VALVE else (D.speed, 0.0, 0.0)  # the pump up to pressure, speed
    closed = module.supply(z, 1.0, 0.0, 1.4, 0.0, 8e6, 2e5, D)
    opened = module.supply(z, 1.0, 1.0, 1.4, 0.0, 8e6, 2e5, D)
    if module.VALVE:
        assert abs(closed.q_a) + abs(closed.q_b) < 0.01 * P.pump_max_flow_m3_s, drive
        assert opened.q_a > 0.1 * P.pump_max_flow_m3_s and opened.q_b < 0.0, drive
    else:
        assert (closed.q_a, closed.q_b) == (opened.q_a, opened.q_b), drive
        if holds_oil(drive):
            assert closed.q_a > 0.5 * P.pump_max_flow_m3_s and closed.q_b < 0.0, drive


@pytest.mark.parametrize("drive", ["fixed_pump", "load_sensing", "pump_controlled"])
def test_a_drive_in_paper_mode_is_refused_in_one_line(drive):
    with pytest.raises(ConfigError, match=rf"drive '{drive}' needs physical mode: .* set mode: physical"):
        from_mapping({"drive": drive, "mode": "paper"})


#: The drives', motor's and battery's parameters (docs/model.md, "Drives", "Battery").
DRIVE_PARAMETERS = (
    "pump_speed_rad_s", "pump_volumetric_efficiency", "pump_hydromechanical_efficiency", "motor_rated_torque_n_m",
    "motor_efficiency", "motor_copper_loss_fraction", "motor_time_constant_s", "battery_capacity_kwh",
    "battery_voltage_v", "battery_resistance_ohm", "battery_initial_soc", "supply_line_volume_m3",
    "main_relief_range_pa", "load_sensing_margin_pa", "load_sensing_time_constant_s", "reservoir_pressure_pa",
    "pilot_check_diameter_m", "pilot_check_opening_pa",
)  # fmt: skip


def test_the_drive_parameters_have_units_and_ranges_and_the_shipped_file_lists_them():
    """Every one is read by a solver now (UNSOLVED is empty), so the node declares it and
    config/default.yaml lists it with its default: existing runs unchanged."""
    assert UNSOLVED == ()
    shipped = config.read_values(CONFIG / "default.yaml")
    for name in DRIVE_PARAMETERS:
        meta = describe(name)
        assert meta["group"] == "plant" and meta["description"], name
        assert meta["unit"] is not None and meta["low"] is not None and meta["high"], name
        assert shipped[name] == getattr(Parameters(), name), name
    assert config.load(CONFIG / "default.yaml") == Parameters()
    with pytest.raises(ConfigError, match=r"'battery_voltage_v'.*must be > 0"):
        from_mapping({"battery_voltage_v": 0.0})


# --- relief valve and fixed pump ------------------------------------------------------


def test_the_main_relief_is_closed_below_p_n_and_passes_the_pump_flow_at_p_n_plus_its_range():
    p_n, span = P.supply_pressure_pa, P.main_relief_range_pa
    flows = [fixed_pump.main_relief_flow_m3_s(p, D) for p in (p_n - 1e5, p_n, p_n + 0.5 * span, p_n + span)]
    assert flows[0] == flows[1] == 0.0
    assert flows[2] == pytest.approx(0.5 * P.pump_max_flow_m3_s, rel=1e-12)
    assert flows[3] == pytest.approx(P.pump_max_flow_m3_s, rel=1e-12)


#: The drives' constants with a valve that leaks nothing: closed, its P paths take nothing.
TIGHT = D._replace(leak=0.0)


def _line_rate(t: float, y: np.ndarray) -> list[float]:
    """The supply line of the fixed pump with the valve closed (its P paths take nothing)."""
    p_t = P.tank_pressure_pa
    s = fixed_pump.supply((y[0], 0.0, 0.0), 0.0, 0.0, 1.4, 0.0, p_t, p_t, TIGHT)
    chain = electric_chain(s, TIGHT)
    losses = chain.battery_loss + chain.motor_loss + chain.pump_volumetric_loss + chain.pump_mechanical_loss
    return [s.rate, chain.battery_power, losses + s.main_relief_loss + s.valve_loss + s.leakage_loss, s.line_oil_work]


def test_a_fixed_pump_dead_heading_settles_at_its_relief_pressure_with_the_line_time_constant():
    """From p_n, where the relief cracks, the line is linear: p_ss + (p_n - p_ss) exp(-t / tau)."""
    p_ss = fixed_pump.dead_head_pressure_pa(D)
    g_total = D.pump_leak + D.g_main
    assert p_ss == pytest.approx(P.supply_pressure_pa + (D.displacement * D.speed - D.pump_leak * (
        P.supply_pressure_pa - P.tank_pressure_pa)) / g_total, rel=1e-12)  # fmt: skip
    tau = P.supply_line_volume_m3 / (P.bulk_modulus_pa * g_total)
    run = solve_ivp(_line_rate, (0.0, 5 * tau), [P.supply_pressure_pa, 0, 0, 0], rtol=1e-10, atol=1e-6,
                    t_eval=[tau, 3 * tau, 5 * tau])  # fmt: skip
    expected = p_ss + (P.supply_pressure_pa - p_ss) * np.exp(-run.t / tau)
    np.testing.assert_allclose(run.y[0], expected, rtol=1e-8)
    assert _line_rate(0.0, np.array([p_ss]))[0] == pytest.approx(0.0, abs=1e-3)  # Pa/s: it holds there


def test_the_fixed_pump_spills_p_n_q_over_the_relief_and_draws_it_from_the_battery_while_the_boom_holds():
    p_ss = fixed_pump.dead_head_pressure_pa(D)
    p_t = P.tank_pressure_pa
    s = fixed_pump.supply((p_ss, 0.0, 0.0), 0.0, 0.0, 1.4, 0.0, p_t, p_t, TIGHT)
    spill = p_ss - P.tank_pressure_pa
    q_pump = pump.delivered_flow_m3_s(D.displacement, D.speed, spill, D.pump_leak)  # eq. D1
    assert s.p_supply == p_ss and s.hydraulic_power == pytest.approx(spill * q_pump, rel=1e-12)
    assert s.main_relief_loss == pytest.approx(spill * q_pump, rel=1e-9)  # all of the pump's flow
    # p_n Q_max, less the pump's leakage (5 % at p_n), plus the relief's override (6 %)
    assert 0.95 < s.main_relief_loss / (P.supply_pressure_pa * P.pump_max_flow_m3_s) < 1.06
    chain = electric_chain(s, D)
    efficiency = P.pump_hydromechanical_efficiency * P.motor_efficiency
    assert chain.battery_power > s.main_relief_loss / efficiency  # and the battery's own loss on top


def test_the_fixed_pump_line_stores_the_compression_energy_its_ledger_says():
    """Ledger over a transient: drawn = losses + oil, and the oil's share is V (p - p_t)^2 / (2 E)."""
    p0, t_end = P.tank_pressure_pa, 0.05
    run = solve_ivp(_line_rate, (0.0, t_end), [p0, 0, 0, 0], rtol=1e-11, atol=[1e-6, 1e-9, 1e-9, 1e-12])
    p_end, drawn, lost, oil = run.y[:, -1]
    compression = P.supply_line_volume_m3 * ((p_end - p0) ** 2) / (2 * P.bulk_modulus_pa)
    assert p_end > P.supply_pressure_pa  # the relief has opened within the transient
    assert oil == pytest.approx(compression, rel=1e-6)
    assert drawn == pytest.approx(lost + oil, rel=1e-9)


# --- load sensing ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("opening", "expected"),
    [(0.5, 9e6 + 2e6), (-0.5, 3e6 + 2e6), (0.0, 1e5 + 2e6), (0.025, 1e5 + 0.5 * (9e6 - 1e5) + 2e6)],
)
def test_load_sensing_heads_for_the_fed_ports_pressure_plus_its_margin(opening, expected):
    assert load_sensing.target_pressure_pa(opening, 9e6, 3e6, D) == pytest.approx(expected, rel=1e-12)


def test_load_sensing_is_capped_at_p_n():
    assert load_sensing.target_pressure_pa(1.0, 15e6, 1e5, D) == P.supply_pressure_pa


def test_load_sensing_tracks_a_rising_load_plus_its_margin_with_the_pumps_lag():
    """A first-order lag behind p1 = p0 + r t settles to p1 + margin - r tau."""
    rate, tau = 5e6, P.load_sensing_time_constant_s  # 5 MPa/s
    p1 = lambda t: 4e6 + rate * t  # noqa: E731

    def f(t, y):
        return [load_sensing.supply((y[0], 0.0, 0.0), 1.0, 1.0, 1.4, 0.1, p1(t), 1e5, D).rate]

    t_end = 20 * tau  # the start's offset has decayed to 1e-9 of itself
    run = solve_ivp(f, (0.0, t_end), [load_sensing.initial_state(D)[0]], rtol=1e-10, atol=1.0)
    assert run.y[0, -1] == pytest.approx(p1(t_end) + P.load_sensing_margin_pa - rate * tau, abs=20.0)


def test_load_sensing_delivers_on_demand_at_its_own_pressure_and_falls_at_the_pumps_flow_limit():
    z, p1 = 8e6, 6e6
    s = load_sensing.supply((z, 0.0, 0.0), 0.1, 0.1, 1.4, 0.0, p1, 1e5, D)
    assert s.p_supply == z and not s.saturated  # a small opening takes less than Q_max
    wide = constants(with_updates(P, orifice_diameter_m=0.006))  # passes Q_max at 0.35 MPa fully open
    limited = load_sensing.supply((z, 0.0, 0.0), 1.0, 1.0, 1.4, 0.0, 7e6, 1e5, wide)
    assert 7e6 < limited.p_supply < z and limited.saturated
    dp = limited.p_supply - 7e6
    assert hydraulics.orifice_flow(wide.k_valve, dp, wide.transition2) == pytest.approx(P.pump_max_flow_m3_s, rel=1e-9)
    # on demand: what the valve's P paths take at the pump's pressure, and the stroke that delivers it
    q_in = valve.paths(0.1, z, p1, 1e5, D).q_in
    dp = z - P.tank_pressure_pa
    assert q_in > 0.0 and s.power == pytest.approx(dp * q_in, rel=1e-12) and s.speed == D.speed
    stroke = s.torque / pump.shaft_torque_n_m(1.0, s.speed, dp, D.torque_loss)  # T is D times T(1)
    assert stroke * s.speed == pytest.approx(q_in + D.pump_leak * dp, rel=1e-12)  # eq. D4


# --- pump, motor, battery -------------------------------------------------------------


def test_the_pump_has_its_stated_efficiencies_pumping_and_the_losses_turn_round_as_a_motor():
    dp, w = P.supply_pressure_pa - P.tank_pressure_pa, P.pump_speed_rad_s
    q = pump.delivered_flow_m3_s(D.displacement, w, dp, D.pump_leak)
    assert q / (D.displacement * w) == pytest.approx(P.pump_volumetric_efficiency, rel=1e-12)
    torque = pump.shaft_torque_n_m(D.displacement, w, dp, D.torque_loss)
    assert D.displacement * dp / torque == pytest.approx(P.pump_hydromechanical_efficiency, rel=1e-4)
    as_motor = pump.shaft_torque_n_m(D.displacement, -w, dp, D.torque_loss)  # the oil drives it
    assert as_motor / (D.displacement * dp) == pytest.approx(2.0 - 1.0 / P.pump_hydromechanical_efficiency, rel=1e-4)
    for speed in (w, -w, 0.3, 0.0):
        loss = pump.mechanical_loss_w(D.displacement, speed, dp, D.torque_loss)
        assert loss >= 0.0 and pump.volumetric_loss_w(dp, D.pump_leak) > 0.0
        shaft = pump.shaft_torque_n_m(D.displacement, speed, dp, D.torque_loss) * speed
        flow = pump.delivered_flow_m3_s(D.displacement, speed, dp, D.pump_leak)
        assert shaft == pytest.approx(dp * flow + pump.volumetric_loss_w(dp, D.pump_leak) + loss, rel=1e-12)


def test_motor_losses_are_the_same_in_both_quadrants_with_eta_motoring_and_2_minus_1_over_eta_generating():
    torque, speed, eta = P.motor_rated_torque_n_m, P.pump_speed_rad_s, P.motor_efficiency
    k_c, k_s = D.motor_copper, D.motor_iron
    m = electric_motor.MotorLosses(k_c, k_s, 0.0, 0.0, 0.0, 0.0)  # the default shares: copper and speed terms alone
    motoring = electric_motor.input_power_w(torque, speed, m)
    generating = electric_motor.input_power_w(-torque, speed, m)
    assert torque * speed / motoring == pytest.approx(eta, rel=1e-12)
    assert generating / (-torque * speed) == pytest.approx(2.0 - 1.0 / eta, rel=1e-12)
    assert generating < 0.0  # it returns power
    loss = electric_motor.motor_loss_w(torque, speed, k_c, k_s)
    assert loss == electric_motor.motor_loss_w(-torque, -speed, k_c, k_s) == pytest.approx(
        torque * speed * (1 / eta - 1), rel=1e-12)  # fmt: skip
    holding = electric_motor.motor_loss_w(0.5 * torque, 0.0, k_c, k_s)  # a torque at standstill: copper only
    assert holding == pytest.approx(0.25 * P.motor_copper_loss_fraction * loss, rel=1e-12)


@pytest.mark.parametrize(("current", "power"), [(10.0, 48 * 10 - 0.1 * 100), (-10.0, -48 * 10 - 0.1 * 100)])
def test_the_battery_current_solves_u_i_minus_r_i2_discharging_and_charging(current, power):
    u, r = 48.0, 0.1
    assert battery.battery_current_a(power, u, r) == pytest.approx(current, rel=1e-12)
    assert battery.chemical_power_w(current, u) == pytest.approx(power + battery.battery_loss_w(current, r), rel=1e-12)
    assert battery.battery_loss_w(current, r) == pytest.approx(10.0, rel=1e-12)  # heat both ways
    capacity = 5.0 * battery.J_PER_KWH
    assert battery.state_of_charge_rate_1_s(current, u, capacity) == pytest.approx(-u * current / capacity)
    assert battery.battery_current_a(power, u, 0.0) == pytest.approx(power / u, rel=1e-12)


def test_the_battery_flags_a_power_beyond_what_it_can_give():
    u, r = 48.0, 0.1
    assert battery.overloaded(0.99 * u * u / (4 * r), u, r) == 0.0
    assert battery.overloaded(1.01 * u * u / (4 * r), u, r) == 1.0


# --- the pump-controlled drive (EHA) --------------------------------------------------


def _lossless_but_copper() -> tuple[Parameters, object]:
    p = with_updates(
        P,
        pump_volumetric_efficiency=1.0,
        pump_hydromechanical_efficiency=1.0,
        motor_copper_loss_fraction=1.0,
        battery_resistance_ohm=0.0,
    )
    return p, constants(p)


def test_the_eha_regenerates_the_pumps_power_less_the_copper_loss_on_lowering():
    """With copper the only loss: U I = D dp w + k_c (D dp)^2, negative for w < 0."""
    p, d = _lossless_but_copper()
    p1, p2, w = 8e6, p.reservoir_pressure_pa, -100.0  # lowering: the load drives the pump
    s = pump_controlled.supply((w, 0.0, 0.0), -1.0, -1.0, 1.4, -0.1, p1, p2, d)
    chain = electric_chain(s, d)
    torque = d.displacement * (p1 - p2)
    expected = torque * w + d.motor_copper * torque**2
    assert chain.battery_power == pytest.approx(expected, rel=1e-12)
    assert chain.battery_power < 0.0 and chain.current < 0.0 and chain.soc_rate > 0.0  # it charges


def _steady_lowering(v: float) -> dict[str, float]:
    """The default EHA lowering the default boom at rod speed ``v`` < 0 at mid-stroke: the motor
    speed that takes S1 |v| out of the piston chamber, and the rod chamber's pressure at which the
    checks pass the area difference to the reservoir."""
    q1 = 1.4
    s1 = geometry.piston_area_m2(P.piston_diameter_m)
    s2 = geometry.annulus_area_m2(P.piston_diameter_m, P.rod_diameter_m)
    force = geometry.static_rod_force_of(P, q1)
    p_r = P.reservoir_pressure_pa

    def p1_of(p2):
        return (force + p2 * s2 + P.ambient_pressure_pa * (s1 - s2)) / s1

    def speed_of(p2):
        return (s1 * v + D.pump_leak * (p1_of(p2) - p2)) / D.displacement  # Q_pump = S1 v

    def rod_line_excess(p2):
        flows = pump_controlled.ports(speed_of(p2), -1.0, p1_of(p2), p2, D)
        return flows.q_b - (-s2 * v)  # into line B less what the rod chamber takes

    p2 = brentq(rod_line_excess, p_r - 4e5, p_r + 4e5, xtol=1e-3)
    p1, w = p1_of(p2), speed_of(p2)
    flows = pump_controlled.ports(w, -1.0, p1, p2, D)
    chain = electric_chain(pump_controlled.supply((w, 0.0, 0.0), -1.0, -1.0, q1, v, p1, p2, D), D)
    return {"p1": p1, "p2": p2, "w": w, "weight_power": force * -v, "hydraulic_power": (p1 - p2) * s1 * -v,
            "returned": -chain.battery_power, "check_b": flows.q_check_b, "area_flow": (s1 - s2) * -v}  # fmt: skip


def test_lowering_through_the_eha_returns_energy_but_less_than_the_potential_energy_given_up():
    run = _steady_lowering(-0.1)
    assert run["w"] < 0.0 and run["p1"] > run["p2"]
    assert 0.0 < run["returned"] < run["hydraulic_power"] < run["weight_power"]
    assert run["returned"] / run["weight_power"] > 0.5  # through pump, motor and battery: 0.89^2 and less
    # the area difference goes to the reservoir through check B, just above its pressure
    assert run["check_b"] == pytest.approx(-run["area_flow"], rel=1e-6)
    assert 0.0 < run["p2"] - P.reservoir_pressure_pa < 0.1e6


def test_each_eha_check_lets_oil_into_its_line_freely_and_out_only_as_far_as_the_other_line_pilots_it():
    """w_A = smoothstep((p2 - p_r) / p_pf), w_B likewise from p1 (eq. D22); a check passes
    K_c f(p_r - p) into its line whatever its pilot, and out of it w K_c f(p_r - p) (eq. D23)."""
    p_r, full = P.reservoir_pressure_pa, P.pilot_check_opening_pa
    assert pump_controlled.pilot_openings(p_r + 0.5 * full, p_r + 0.25 * full, D) == pytest.approx((0.15625, 0.5))
    assert pump_controlled.pilot_openings(p_r + 2.0 * full, p_r, D) == (0.0, 1.0)
    assert pump_controlled.pilot_openings(p_r - full, p_r + full, D) == (1.0, 0.0)
    for dp in (2e5, 5e3, 0.5, -0.5, -5e3, -2e5):  # the reservoir's pressure less the line's
        free = D.k_check * hydraulics.orifice_flow(1.0, dp, D.transition2)
        for pilot in (0.0, 0.3, 1.0):
            expected = free if dp > 0.0 else pilot * free
            assert pump_controlled.check_flow_m3_s(p_r - dp, pilot, D) == pytest.approx(expected, rel=1e-12), dp


def test_the_eha_lifts_with_make_up_oil_from_the_reservoir_and_the_motor_follows_its_command():
    p1, p2 = 8e6, 4e5  # the rod line below the reservoir: check B lets oil in
    flows = pump_controlled.ports(100.0, 1.0, p1, p2, D)
    assert flows.q_pump > 0.0 and flows.q_check_b > 0.0 and flows.q_check_a == pytest.approx(0.0, abs=1e-12)
    s = pump_controlled.supply((100.0, 0.0, 0.0), 1.0, 1.0, 1.4, 0.05, p1, p2, D)
    assert (s.q_a, s.q_b) == (flows.q_a, flows.q_b)
    assert s.rate == pytest.approx((P.pump_speed_rad_s - 100.0) / P.motor_time_constant_s, rel=1e-12)
    assert s.valve_loss > 0.0 and s.reservoir_power > 0.0  # the checks' throttling, the make-up oil
    assert electric_chain(s, D).battery_power > 0.0


def test_without_a_motor_lag_the_speed_is_the_command():
    d = constants(with_updates(P, motor_time_constant_s=0.0))
    assert pump_controlled.motor_speed_rad_s(12.0, -0.5, d) == -0.5 * P.pump_speed_rad_s
    s = pump_controlled.supply((12.0, 0.0, 0.0), -0.5, -0.5, 1.4, 0.0, 5e6, 5e5, d)
    assert s.rate == 0.0 and s.speed == -0.5 * P.pump_speed_rad_s


def test_the_elements_take_arrays_as_they_take_floats():
    """A batch evaluates the drives on numpy arrays (xp=numpy) to the same values."""
    p1 = np.array([3e6, 9e6, 2e5])
    p2 = np.array([5e5, 6e5, 1e6])
    w = np.array([50.0, -80.0, 0.0])
    zero = 0.0 * w
    supplied = pump_controlled.supply((w, zero, zero), 0.3, 0.3, 1.4, 0.0, p1, p2, D, np)
    arrays = electric_chain(supplied, D, np)
    for k in range(3):
        single = pump_controlled.supply((w[k], 0.0, 0.0), 0.3, 0.3, 1.4, 0.0, p1[k], p2[k], D)
        one = electric_chain(single, D)
        assert [float(a[k]) for a in arrays] == pytest.approx(list(one), rel=1e-12, abs=1e-15)
        assert [float(np.asarray(a)[k]) for a in supplied] == pytest.approx(list(single), rel=1e-12, abs=1e-15)
    assert math.isfinite(float(arrays.battery_power[2]))


# --- the drives' constants and a batch's choice of drive ---------------------------------


def test_the_drive_constants_are_their_parameters_by_the_models_definitions():
    """The derived constants against their definitions (docs/model.md, "Drives"): D = Q_max / w_n
    (eq. D4), G_mr = Q_max / range (eq. D12), p_tr^2, K / sqrt(p_tr), E_usable in J, the lags'
    reciprocals, the screw's r = l / (2 pi N) and its friction m, d such that driving it costs
    1 / eta_f and back-driving it gives eta_b (eq. D30, D32), K_w = J_m w_c (eq. D34)."""
    p = with_updates(P, motor_time_constant_s=0.2, load_sensing_time_constant_s=0.3, ema_gear_ratio=3.0,
                     ema_forward_efficiency=0.8, ema_backdrive_efficiency=0.6, battery_capacity_kwh=2.5)  # fmt: skip
    d = constants(p)
    assert d.displacement == p.pump_max_flow_m3_s / p.pump_speed_rad_s
    assert d.g_main == p.pump_max_flow_m3_s / p.main_relief_range_pa
    assert d.transition2 == pytest.approx(p.transition_pressure_pa**2, rel=1e-15)
    assert d.k_laminar == pytest.approx(d.k_valve / math.sqrt(p.transition_pressure_pa), rel=1e-15)
    assert d.battery_capacity == 2.5 * 3.6e6  # J: 1 kWh is 3.6 MJ
    assert (d.motor_lag, d.motor_inv_tau, d.ls_inv_tau) == (1.0, pytest.approx(5.0), pytest.approx(1 / 0.3))
    ratio = p.ema_screw_lead_m / (2.0 * math.pi * 3.0)
    assert d.ema_ratio == pytest.approx(ratio, rel=1e-15)
    assert 1.0 + d.ema_friction_skew + d.ema_friction_mean == pytest.approx(1 / 0.8, rel=1e-15)  # driving it
    assert 1.0 + d.ema_friction_skew - d.ema_friction_mean == pytest.approx(0.6, rel=1e-15)  # back-driven
    assert d.ema_speed_gain == p.ema_inertia_kg_m2 * p.ema_speed_bandwidth_rad_s
    assert (D.motor_lag, D.motor_inv_tau) == (1.0, 1.0 / P.motor_time_constant_s)
    quick = constants(with_updates(P, motor_time_constant_s=0.0))  # no lag: the speed is the command
    assert (quick.motor_lag, quick.motor_inv_tau) == (0.0, 0.0)


def _as_read(word: str) -> str:
    """``word`` as a file's reader builds it: equal to the literal, not the same (interned) object."""
    return "".join(list(word))


@pytest.mark.parametrize("drive", DRIVE_CHOICES)
def test_each_drive_is_its_index_in_the_registry_and_sets_its_rod_speed_at_full_command(drive):
    """The drives without the 4/3 valve set the rod's speed at full command by their motor's top
    speed: the EHA D w_max / S1 (eq. D20), the actuator r w_n (eq. D30); the valve drives 0."""
    p = with_updates(P, drive=_as_read(drive), ema_gear_ratio=3.0)
    d = constants(p)
    assert d.drive == DRIVE_CHOICES.index(drive)
    expected = {
        "pump_controlled": p.pump_max_flow_m3_s / geometry.piston_area_m2(p.piston_diameter_m),
        "electro_mechanical": p.ema_screw_lead_m / (2.0 * math.pi * 3.0) * p.pump_speed_rad_s,
    }.get(drive, 0.0)
    assert d.command_rod_speed == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize(
    ("limit", "integral_s", "torque_max", "inv_integral"),
    [(0.0, 0.3, 0.0, 0.0), (0.5, 0.3, 0.5, 1 / 0.3), (200.0, 0.3, 0.3 * 375.0, 1 / 0.3), (200.0, 0.0, 112.5, 0.0)],
)
def test_the_eha_as_built_is_on_with_a_torque_limit_and_its_speed_loop_integrates_with_an_integral_time(
    limit, integral_s, torque_max, inv_integral
):
    """eq. D50-D52: T_max = min(limit, k_t I_max), J and 1 / J of the rotors, 1 / T_i, all 0
    without a torque limit (the lag instead); a T_i of 0 makes the loop proportional."""
    p = with_updates(P, eha_torque_limit_n_m=limit, eha_speed_integral_time_s=integral_s,
                     eha_torque_constant_n_m_a=0.3, eha_current_limit_a=375.0,
                     eha_motor_inertia_kg_m2=0.03)  # fmt: skip
    d = constants(p)
    on = 1.0 if limit else 0.0
    assert d.eha_torque_model == on and d.eha_torque_max == pytest.approx(torque_max, rel=1e-15)
    assert (d.eha_inertia, d.eha_inv_inertia) == (on * 0.03, pytest.approx(on / 0.03, rel=1e-15))
    assert d.eha_inv_integral_time == pytest.approx(inv_integral, rel=1e-15)


def test_the_choices_of_a_parameters_file_set_their_flags_and_indices():
    """The load-holding valves, the motor's strategy (its index in motor_speed.STRATEGIES) and
    the valve's centre, each chosen by a word as a file's reader builds it."""
    for strategy, index in (("constant", 0.0), ("idle_stop", 1.0), ("speed_on_demand", 2.0)):
        assert constants(with_updates(P, motor_strategy=_as_read(strategy))).motor_strategy == index, strategy
    for choice, flag in (("piston_side", 1.0), ("none", 0.0)):
        d = constants(with_updates(P, load_holding_valve=_as_read(choice), eha_holding_valve=_as_read(choice)))
        assert (d.holding, d.eha_holding) == (flag, flag), choice
    for centre, flag in (("open", 1.0), ("closed", 0.0)):
        assert constants(with_updates(P, valve_centre=_as_read(centre))).open_centre == flag, centre


def _supplies() -> tuple[Supply, Supply]:
    """Two drives' supplies whose every field differs, by neither 0 nor 1."""
    n = len(Supply._fields)
    return Supply(*(1.5 + k for k in range(n))), Supply(*(-4.25 - 3.0 * k for k in range(n)))


def test_a_batch_gives_each_set_its_own_drives_supply_and_one_set_the_drive_itself():
    """blend: a set whose drive's flag is 1 takes that drive's every field, one whose flag is 0
    keeps the other's; chosen: one set's drive is the drive itself, a batch's the blend."""
    a, b = _supplies()
    w = np.array([0.0, 1.0])
    for name, mixed, first, second in zip(Supply._fields, blend(a, b, w), a, b):
        assert list(mixed) == [first, second], name
    assert chosen(a, b, 1.0) is b
    assert [list(x) for x in chosen(a, b, w)] == [list(x) for x in blend(a, b, w)]
    assert in_use(1.0) and not in_use(0.0)
    assert in_use(np.array([0.0, 1.0])) and not in_use(np.array([0.0, 0.0]))


def test_the_compiled_forms_of_in_use_and_chosen_answer_as_the_python_ones():
    """What numba runs for in_use and chosen (their typing functions' implementations, called here
    as Python): a set's flag, any set's flag in a batch; one set's drive itself, a batch's blend."""
    import numba

    from boom_hydraulics.model.drives.constants import _chosen_compiled, _in_use_compiled

    flags = (0.0, 1.0, np.array([0.0, 0.0]), np.array([0.0, 1.0]))
    for flag in flags:
        assert bool(_in_use_compiled(numba.float64)(flag)) == in_use(flag), flag
    a, b = _supplies()
    assert _chosen_compiled(a, b, numba.float64)(a, b, 1.0) is b
    w = np.array([0.0, 1.0])
    batch = _chosen_compiled(a, b, numba.float64[:])(a, b, w)
    assert [list(x) for x in batch] == [list(x) for x in blend(a, b, w)]
