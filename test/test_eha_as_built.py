"""The EHA (pump_controlled) as built: its motor's torque-limited speed loop on the rotors'
inertia, the inverter's standby power and the load-holding valve (docs/model.md, "The EHA as
built", eq. D50-D56). Each is off by default, and the EHA's results at the defaults are those
recorded at d39ea8d, before any of them existed."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from boom_hydraulics.model import ledger, physical, pump
from boom_hydraulics.model.drives import constants, eha_motor, pump_controlled
from boom_hydraulics.model.parameters import Parameters, with_updates
from boom_hydraulics.solve import commands, duty_cycles
from boom_hydraulics.solve.simulation import Simulator

EHA = with_updates(Parameters(), drive="pump_controlled")
#: The motor controller's torque limit the tests switch on, N m: 15.6 MPa across the default pump.
TORQUE_LIMIT_N_M = 55.0
STANDBY_W = 30.0
#: Everything as built switched on.
AS_BUILT = {
    "eha_torque_limit_n_m": TORQUE_LIMIT_N_M,
    "eha_holding_valve": "piston_side",
    "inverter_standby_power_w": STANDBY_W,
}
#: The brief's end-stop run: full speed out into the stop, hold, full speed in, hold.
STOPS = "steps:0=1,3=0,4=-1,7=0"
#: Recorded before the EHA was built (tools/with-env python, Simulator compiled, every=10): the
#: default EHA's ledger over the loader cycle and over STOPS (9 s), J, and its final cylinder
#: length, m. STOPS at d39ea8d; the loader cycle once the position controller's feedforward took
#: the EHA's own rod speed at full command (D w_max / S1) in place of the valve's law.
RECORDED = {
    "loader": {
        "battery_drawn": 2179.0374896691624,
        "battery_returned": 510.4842702218557,
        "lift_work": 1234.3107717605244,
        "port_relief_loss": 0.0,
        "q1": 1.369169408930717,
    },
    STOPS: {
        "battery_drawn": 55896.35159292596,
        "battery_returned": 2835.8469693089487,
        "lift_work": 1666.0974080978335,
        "port_relief_loss": 33782.66606613055,
        "q1": 1.0499349972792154,
    },
}


@functools.cache
def _run(profile: str, duration_s: float, **updates) -> tuple[dict[str, float], dict[str, np.ndarray], list, list]:
    """The ledger's integrals (J, by name), the outputs (every step), the first and last state
    of the EHA with ``updates`` on ``profile``."""
    params = with_updates(EHA, **updates)
    params = with_updates(params, **commands.scenario(profile, duration_s, params))
    sim = Simulator(params)
    start = list(sim.y)
    out = sim.run(duration_s, commands.from_parameters(params), every=1)
    integrals = physical.ledger_integrals(sim.y)
    return integrals, out.columns, start, list(sim.y)


@pytest.mark.parametrize("profile", ["loader", STOPS])
def test_at_its_defaults_the_eha_gives_the_results_recorded_before_it_was_built(profile):
    duration = duty_cycles.LOADER_DURATION_S if profile == "loader" else 9.0
    integrals, _, _, end = _run(profile, duration)
    recorded = RECORDED[profile]
    for name in ("battery_drawn", "battery_returned", "lift_work", "port_relief_loss"):
        assert integrals[name] == pytest.approx(recorded[name], rel=1e-9, abs=1e-9), name
    assert integrals["standby_loss"] == 0.0 and integrals["rotor_power"] == 0.0
    assert end[0] == pytest.approx(recorded["q1"], rel=1e-12)


def _stall_pressure_pa(d) -> float:
    """dp = T_max / (D (1 + c_f)): where the pump's torque (eq. D2) meets the torque limit."""
    return d.eha_torque_max / (d.displacement * (1.0 + d.torque_loss))


def test_held_against_its_end_stop_the_motor_stalls_at_its_torque_limit_and_the_reliefs_stay_shut():
    """Full speed out into the stop and held there: the reliefs take the impact's surge only;
    stalled, the pump holds dp = T_max / (D (1 + c_f)) and nothing goes over them. Without the
    torque limit, the motor keeps its speed and the reliefs take most of the battery's energy."""
    duration = 8.0
    integrals, out, _, _ = _run("steps:0=1", duration, eha_torque_limit_n_m=TORQUE_LIMIT_N_M)
    d = constants(with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M))
    t, relief = out["t"], out["port_relief_loss_j"]
    stopped = t[np.argmax(out["at_end_stop"] > 0.5)]
    assert 0.5 < stopped < 2.0  # it reached the stop
    settled = t >= stopped + 1.0
    assert relief[-1] - relief[settled][0] < 1e-6 * integrals["battery_drawn"]  # stalled: nothing over them
    assert out["p1"].max() < 1.3 * Parameters().relief_pressure_pa  # the surge stays within the relief's range
    assert integrals["port_relief_loss"] < 0.05 * integrals["battery_drawn"]
    last = t >= duration - 1.0
    dp = np.mean(out["p1"][last] - out["p2"][last])
    assert dp == pytest.approx(_stall_pressure_pa(d), rel=5e-3)
    assert out["p1"][last].max() < Parameters().relief_pressure_pa
    today, _, _, _ = _run("steps:0=1", duration)
    assert today["port_relief_loss"] > 0.5 * today["battery_drawn"]  # the lag model: a speed source


def test_on_the_end_stop_run_the_reliefs_take_a_fraction_of_what_they_took():
    """The brief's run (out into the stop, in into the other): the torque limit leaves the
    reliefs the two impacts' surges, a sixth of the share they took as a speed source."""
    limited, _, _, _ = _run(STOPS, 9.0, eha_torque_limit_n_m=TORQUE_LIMIT_N_M)
    share = limited["port_relief_loss"] / limited["battery_drawn"]
    recorded = RECORDED[STOPS]
    assert share < recorded["port_relief_loss"] / recorded["battery_drawn"] / 5.0
    assert limited["battery_drawn"] < 0.25 * recorded["battery_drawn"]


def test_the_stored_energy_holds_the_rotors_kinetic_energy():
    """Stopped at full speed on the way out (the rotors hold J w_max^2 / 2, 123 J), the stored
    energy H has changed as the integral of its rate W says (the stepping's energy check)."""
    _, _, start, end = _run("steps:0=1", 0.9, eha_torque_limit_n_m=TORQUE_LIMIT_N_M)
    c = physical.constants(with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M))
    speed = end[physical.DRIVE_STATE]
    assert speed == pytest.approx(EHA.pump_speed_rad_s, rel=0.05)
    change = physical.energy(end, c) - physical.energy(start, c)
    w_index, w_abs_index = physical.ENERGY_STATES
    assert change == pytest.approx(end[w_index] - start[w_index], abs=1e-5 * end[w_abs_index])
    assert 0.5 * EHA.eha_motor_inertia_kg_m2 * speed**2 > 1e-2 * end[w_abs_index]  # what the check would miss


def _rk4(f, y: np.ndarray, dt: float) -> np.ndarray:
    k1 = f(y)
    k2 = f(y + 0.5 * dt * k1)
    k3 = f(y + 0.5 * dt * k2)
    k4 = f(y + dt * k3)
    return y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def test_a_speed_step_ramps_at_the_torque_limit_over_the_inertia_then_holds_the_commanded_speed():
    """Across fixed line pressures, J w' = T_max - T_pump while the torque is limited: for
    w >> w_f the ramp's slope is (T_max - D dp (1 + c_f)) / J (eq. D2, D50, D51); the PI loop
    then holds u w_max without droop, and the shaft's power is the pump's plus J w w'."""
    p = with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M)
    d = constants(p)
    p1, p2, u = 8.0e6, p.reservoir_pressure_pa, 0.8

    def supply(y):
        return pump_controlled.supply((y[0], y[1], 0.0), u, 0.0, 1.4, 0.0, p1, p2, d)

    def rates(y):
        s = supply(y)
        return np.array([s.rate, s.rate2])

    dt, y, t = 1e-5, np.zeros(2), 0.0
    times, speeds = [], []
    while t < 0.4:
        y = _rk4(rates, y, dt)
        t += dt
        times.append(t)
        speeds.append(y[0])
    times, speeds = np.array(times), np.array(speeds)
    load = d.displacement * (p1 - p2) * (1.0 + d.torque_loss)
    slope = (d.eha_torque_max - load) / p.eha_motor_inertia_kg_m2
    ramp = (speeds > 20.0) & (speeds < 0.8 * u * d.speed)
    measured = np.polyfit(times[ramp], speeds[ramp], 1)[0]
    assert measured == pytest.approx(slope, rel=2e-3)  # c_f w / sqrt(w^2 + w_f^2) within 0.13 % of c_f
    s = supply(np.array([50.0, 0.0]))
    assert s.torque == d.eha_torque_max and s.rotor_power == pytest.approx(50.0 * (s.torque - load), rel=2e-3)
    assert speeds[-1] == pytest.approx(u * d.speed, rel=1e-3)  # no droop under the load


def test_standby_adds_its_power_times_the_time_to_the_battery_energy_at_rest():
    duration = 2.0
    rest = {"battery_resistance_ohm": 0.0}  # U I = P_el: the battery adds nothing of its own
    without, _, _, _ = _run("constant:0", duration, **rest)
    standby, _, _, _ = _run("constant:0", duration, inverter_standby_power_w=STANDBY_W, **rest)
    drawn = standby["battery_drawn"] - standby["battery_returned"]
    drawn_before = without["battery_drawn"] - without["battery_returned"]
    assert drawn - drawn_before == pytest.approx(STANDBY_W * duration, rel=1e-9)
    assert standby["standby_loss"] == pytest.approx(STANDBY_W * duration, rel=1e-12)


#: Where each hold of the loader cycle ends: before the next move, or the payload's release.
HOLD_ENDS_S = (duty_cycles.LOADER_TIMES_S[1], duty_cycles.LOADER_TIMES_S[2], duty_cycles.LOADER_TIMES_S[4],
               duty_cycles.LOADER_DURATION_S)  # fmt: skip
MOVE_STARTS_S = (0.0, duty_cycles.LOADER_TIMES_S[1], duty_cycles.LOADER_TIMES_S[3], duty_cycles.LOADER_TIMES_S[4])


def _holds(out: dict[str, np.ndarray]) -> list[float]:
    """The tip's travel (boom length x the angle's range), m, in each hold of the loader cycle
    that the position loop closed (its command exactly 0 at rest), from 0.5 s after it closed
    (the boom's stop has rung out) to the hold's end."""
    t, alpha, u = out["t"], out["alpha"], out["u"]
    travels = []
    for start, end in zip(MOVE_STARTS_S, HOLD_ENDS_S, strict=True):
        phase = (t > start + 0.5) & (t < end)
        closed = np.nonzero(phase & (u == 0.0))[0]
        if len(closed):
            hold = phase & (t >= t[closed[0]] + 0.5)
            travels.append(Parameters().boom_length_m * float(np.ptp(alpha[hold])))
    return travels


def _overshoot_rad(out: dict[str, np.ndarray], p: Parameters) -> float:
    """The largest overshoot of the loader cycle's moves past their targets, rad."""
    t, alpha = out["t"], out["alpha"]
    cycle = duty_cycles.loader(p)
    worst = 0.0
    for start, end, target in zip(MOVE_STARTS_S, HOLD_ENDS_S, cycle["command_angles_rad"], strict=True):
        phase = (t >= start) & (t < end)
        direction = math.copysign(1.0, target - alpha[phase][0])
        worst = max(worst, float(np.max(direction * (alpha[phase] - target))))
    return worst


@functools.cache
def _loader(**updates) -> tuple[dict[str, float], dict[str, np.ndarray], list, list]:
    return _run("loader", duty_cycles.LOADER_DURATION_S, **updates)


def test_with_the_load_holding_valve_the_boom_holds_still_where_the_eha_hunted():
    _, today, _, _ = _loader()
    _, built, _, _ = _loader(**AS_BUILT)
    hunted, held = _holds(today), _holds(built)
    assert hunted and max(hunted) > 3e-3  # the pump's leakage sinks the boom, the loop lifts it again
    assert held and max(held) < 1e-3
    valve_alone = _holds(_loader(eha_holding_valve="piston_side")[1])  # the lag's speed source, valve on
    assert valve_alone and max(valve_alone) < 1e-3
    assert _overshoot_rad(built, EHA) < 0.75 * _overshoot_rad(today, EHA)


def test_the_ledger_closes_over_the_loader_cycle_with_everything_on():
    integrals, out, start, end = _loader(**AS_BUILT)
    assert ledger.energies_of(integrals)["imbalance_ratio"] < 1e-9
    assert integrals["standby_loss"] == pytest.approx(STANDBY_W * duty_cycles.LOADER_DURATION_S, rel=1e-12)
    assert integrals["valve_loss"] > 0.0 and integrals["leakage_loss"] > 0.0  # the holding valve throttles and seeps
    inertia = EHA.eha_motor_inertia_kg_m2
    rotor = 0.5 * inertia * (end[physical.DRIVE_STATE] ** 2 - start[physical.DRIVE_STATE] ** 2)
    assert integrals["rotor_power"] == pytest.approx(rotor, abs=1e-3)  # rk4's error: 2.5e-4 J (123 J at top speed)
    assert out["battery_returned"][-1] > 0.0  # it still regenerates on lowering


def test_at_random_states_the_ledger_closes_at_each_instant_with_everything_on():
    """Eq. D29 is an identity of the model's equations with the motor's inertia, its standby
    and the holding valve (open, closing or shut), as with the lag."""
    c = physical.constants(with_updates(EHA, **AS_BUILT))
    rng = np.random.default_rng(50)
    y = physical.initial_state(with_updates(EHA, **AS_BUILT))
    for _ in range(200):
        y = list(y)
        y[0] = rng.uniform(EHA.cylinder_min_length_m, EHA.cylinder_max_length_m)
        y[1] = rng.uniform(-0.3, 0.3)
        y[2], y[3] = rng.uniform(2e5, 1.9e7, size=2)
        y[physical.DRIVE_STATE] = rng.uniform(-170.0, 170.0)
        y[physical.DRIVE_STATE + 1] = rng.uniform(-30.0, 30.0)
        u = rng.choice([0.0, rng.uniform(-0.02, 0.02), rng.uniform(-1.0, 1.0)])
        terms = physical.ledger(0.0, y, c, u)
        scale = sum(abs(v) for v in terms)
        assert abs(ledger.residual_w(terms)) < 1e-9 * scale


def test_with_everything_on_the_eha_takes_arrays_as_it_takes_floats():
    """A batch evaluates the drive on numpy arrays (xp=numpy): the same values, set by set."""
    d = constants(with_updates(EHA, **AS_BUILT))
    w = np.array([120.0, -80.0, 0.0, 0.4])
    integral = np.array([5.0, -3.0, 0.0, 1.0])
    u = np.array([0.7, -0.5, 0.0, 0.004])
    p1 = np.array([9e6, 6e6, 4e6, 1.2e7])
    p2 = np.array([5e5, 5.2e5, 5e5, 6e5])
    arrays = pump_controlled.supply((w, integral, 0.0 * w), u, 0.0, 1.4, 0.0, p1, p2, d, np)
    for k in range(len(w)):
        one = pump_controlled.supply((w[k], integral[k], 0.0), u[k], 0.0, 1.4, 0.0, p1[k], p2[k], d)
        assert [float(np.asarray(a)[k]) if np.ndim(a) else float(a) for a in arrays] == pytest.approx(
            list(one), rel=1e-12, abs=1e-15
        )


#: The load-holding valve on, with the lag's speed source (VALVE) and with the torque-limited motor (VALVE_LOOP).
VALVE = constants(with_updates(EHA, eha_holding_valve="piston_side"))
VALVE_LOOP = constants(with_updates(EHA, eha_holding_valve="piston_side", eha_torque_limit_n_m=TORQUE_LIMIT_N_M))


@pytest.mark.parametrize(
    ("share", "speed_share", "lag_opening", "loop_opening"),
    [(0.0, 0.0, 0.0, 0.0), (1.0, 0.0, 1.0, 1.0), (-1.0, 0.0, 1.0, 1.0), (0.5, 0.0, 0.5, 0.5),
     (-0.25, 0.0, 0.15625, 0.15625), (3.0, 0.0, 1.0, 1.0), (0.0, 1.0, 1.0, 0.0), (0.0, -0.5, 0.5, 0.0),
     (0.25, -1.0, 1.0, 0.15625)],
)  # fmt: skip
def test_the_holding_valve_opens_smoothly_up_to_its_command_share_and_only_the_lag_holds_it_open_running_down(
    share, speed_share, lag_opening, loop_opening
):
    """w_h = smoothstep(max(|u|, |w| / w_max) / u_h) (eq. D53): shut at rest, fully open from
    u_h of top speed commanded either way, half at u_h / 2; with the lag's speed source the
    running-down motor holds it open, with the torque-limited loop the command alone does
    (the shut valve stops the rotors itself). Without the valve: always 1 (open)."""
    u = share * EHA.eha_holding_command
    speed = speed_share * EHA.eha_holding_command * EHA.pump_speed_rad_s
    assert pump_controlled.holding_opening(speed, u, VALVE) == pytest.approx(lag_opening, rel=1e-12, abs=1e-15)
    assert pump_controlled.holding_opening(speed, u, VALVE_LOOP) == pytest.approx(loop_opening, rel=1e-12, abs=1e-15)
    assert pump_controlled.holding_opening(speed, u, constants(EHA)) == 1.0


@pytest.mark.parametrize("flow", [2e-4, -2e-4, 3e-7, 0.0])
@pytest.mark.parametrize("opening", [1.0, 0.3, 0.0])
def test_the_pump_side_of_the_load_holding_valve_is_where_the_pumps_leakage_and_the_orifice_pass_its_flow(
    flow, opening
):
    """x solves G_p x + K_h sign(x) sqrt|x| = Q0 (eq. D54), K_h = w_h K_c: the pump's flow at p1
    less what its leakage loses at the higher port pressure is what the valve's orifice passes
    (shut, the leakage alone: x = Q0 / G_p); without the valve x = 0."""
    x = pump_controlled.holding_drop_pa(flow, opening, VALVE)
    k_h = opening * VALVE.k_check
    assert VALVE.pump_leak * x + k_h * math.copysign(math.sqrt(abs(x)), x) == pytest.approx(flow, rel=1e-9, abs=1e-18)
    assert math.copysign(1.0, x) == math.copysign(1.0, flow) or flow == x == 0.0
    assert pump_controlled.holding_drop_pa(flow, opening, constants(EHA)) == 0.0


def test_the_shut_load_holding_valve_seals_the_piston_chamber_but_for_its_seat_and_the_pump_sees_no_load():
    """Command 0, motor at rest, the valve shut (eq. D53-D55): the pump's port holds no pressure
    (its leakage takes nothing), only the seat leaks from line A to line B; without the valve the
    pump's leakage takes G_p (p1 - p2) from the loaded chamber."""
    p1, p2 = 8e6, 4.5e5
    shut = pump_controlled.ports(0.0, 0.0, p1, p2, VALVE)
    assert shut.dp_pump == pytest.approx(0.0, abs=1e-6) and shut.q_pump == pytest.approx(0.0, abs=1e-18)
    assert shut.valve_drop == pytest.approx(-(p1 - p2), rel=1e-12)
    assert shut.q_seat == pytest.approx(EHA.load_holding_leakage_m3_s_pa * (p1 - p2), rel=1e-12)
    assert shut.q_a == pytest.approx(shut.q_check_a - shut.q_seat, rel=1e-12)
    assert shut.q_b == pytest.approx(shut.q_check_b + shut.q_seat, rel=1e-12)
    open_ = pump_controlled.ports(0.0, 0.0, p1, p2, constants(EHA))
    assert open_.q_seat == 0.0 and open_.valve_drop == 0.0 and open_.dp_pump == p1 - p2
    assert open_.q_pump == pytest.approx(-VALVE.pump_leak * (p1 - p2), rel=1e-12)


@pytest.mark.parametrize("holding", ["none", "piston_side"])
def test_the_stability_bound_is_the_lags_rate_or_the_speed_loops_and_each_line_sees_its_check_and_the_pumps_leakage(
    holding,
):
    """The lines' dQ/dp: a check's laminar slope K_c / sqrt(p_tr) and the pump's leakage G_p. The
    drive's own fastest rate: 1 / tau with the lag; with the torque-limited loop its bandwidth
    K_w / J and 1 / T_i, the rotors on the chambers' oil springs through the pump sqrt(D^2 (s1 +
    s2) / J), the pump's friction through standstill c_f D 2 p_n / (w_f J) and, with the valve,
    the pump against the shut valve, its leakage alone taking its flow, D^2 (1 + c_f) / (G_p J)."""
    stiff1, stiff2 = 2.0e-2, 5.0e-3
    lag = constants(with_updates(EHA, eha_holding_valve=holding))
    check = lag.k_check / math.sqrt(EHA.transition_pressure_pa) + lag.pump_leak
    line_a, line_b, own = pump_controlled.stiffness((0.0, 0.0, 0.0), 0.5, 0.0, stiff1, stiff2, 1e-3, lag)
    assert (line_a, line_b) == pytest.approx((check, check), rel=1e-12)
    assert own == pytest.approx(1.0 / EHA.motor_time_constant_s, rel=1e-12)
    loop = constants(with_updates(EHA, eha_holding_valve=holding, eha_torque_limit_n_m=TORQUE_LIMIT_N_M))
    j, dd, c_f = EHA.eha_motor_inertia_kg_m2, loop.displacement**2, loop.torque_loss
    expected = EHA.eha_speed_gain_n_m_s_rad / j + 1.0 / EHA.eha_speed_integral_time_s
    expected += math.sqrt(dd * (stiff1 + stiff2) / j)
    expected += c_f * loop.displacement * 2.0 * EHA.supply_pressure_pa / j  # w_f = 1 rad/s
    expected += (holding == "piston_side") * dd * (1.0 + c_f) / (loop.pump_leak * j)
    line_a, line_b, own = pump_controlled.stiffness((0.0, 0.0, 0.0), 0.5, 0.0, stiff1, stiff2, 1e-3, loop)
    assert (line_a, line_b) == pytest.approx((check, check), rel=1e-12)
    assert own == pytest.approx(expected, rel=1e-12)


def test_the_eha_starts_with_its_motor_at_rest_and_its_speed_loop_empty():
    """The initial state: the motor's speed 0 and the loop's integral 0, so that at command 0 the
    motor asks no torque and stays at rest (eq. D50-D52)."""
    p = with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M)
    d = constants(p)
    z = pump_controlled.initial_state(d)
    assert z == (0.0, 0.0, 0.0)
    y = physical.initial_state(p)
    assert list(y[physical.DRIVE_STATE : physical.DRIVE_STATE + 2]) == [0.0, 0.0]
    s = pump_controlled.supply(z, 0.0, 0.0, 1.4, 0.0, 5e5, 5e5, d)
    assert s.torque == 0.0 and s.rate2 == 0.0


@pytest.mark.parametrize(
    ("error", "asked"),
    [(0.0, 0.0), (10.0, 20.0), (-10.0, -20.0), (27.5, 55.0), (-27.5, -55.0), (27.6, 55.0), (-27.6, -55.0),
     (90.0, 55.0)],
)  # fmt: skip
def test_the_speed_loop_asks_its_gain_times_the_error_within_the_torque_limit_and_its_integral_relaxes_to_the_limit(
    error, asked
):
    """T_m = clamp(K_w (u w_max - w + I), -T_max, T_max) (eq. D50), with K_w = 2 N m s/rad and
    T_max = 55 N m: the limit exactly at an error of 27.5 rad/s either way, held past it. The
    rotors of J take T_m less the pump's torque (eq. D51), J w w' of it is their power, and the
    loop's integral relaxes at 1 / T_i to T_m / K_w (eq. D52): with the torque limited, to the
    limit's share, not on (no wind-up)."""
    d = constants(with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M))
    assert (d.eha_speed_gain, d.eha_torque_max) == (2.0, TORQUE_LIMIT_N_M)
    u, integral = 0.5, 3.0
    speed = u * d.speed + integral - error  # the loop's error u w_max - w + I
    assert eha_motor.torque_n_m(speed, integral, u, d) == pytest.approx(asked, rel=1e-12, abs=1e-12)
    pump_torque = 12.0
    m = eha_motor.motor(speed, integral, u, pump_torque, d)
    assert m.torque == pytest.approx(asked, rel=1e-12, abs=1e-12)
    j, t_i = EHA.eha_motor_inertia_kg_m2, EHA.eha_speed_integral_time_s
    assert m.speed_rate == pytest.approx((asked - pump_torque) / j, rel=1e-12)
    assert m.rotor_power == pytest.approx(j * speed * m.speed_rate, rel=1e-12)
    assert m.integral_rate == pytest.approx((asked / 2.0 - integral) / t_i, rel=1e-12, abs=1e-12)


def test_the_open_load_holding_valves_seat_leaks_nothing_and_a_half_shut_one_half_its_leakage():
    """q_seat = (1 - w_h) G_seat (p1 - p2) (eq. D55): none with the valve open (commanded past u_h),
    all of it shut, half at w_h = 1/2 (u_h / 2 commanded)."""
    p1, p2 = 8e6, 4.5e5
    leak = EHA.load_holding_leakage_m3_s_pa * (p1 - p2)
    assert pump_controlled.ports(100.0, 1.0, p1, p2, VALVE).q_seat == 0.0
    half = pump_controlled.ports(0.0, 0.5 * EHA.eha_holding_command, p1, p2, VALVE).q_seat
    assert half == pytest.approx(0.5 * leak, rel=1e-12)


def test_with_the_torque_limited_motor_the_rotors_accelerate_at_the_motors_less_the_pumps_torque_over_j():
    """J w' = T_m - T_p (eq. D51), T_m = K_w (u w_max - w + I) below the limit (eq. D50), the
    pump's T_p at its speed and pressure rise (eq. D2); I' = (T_m / K_w - I) / T_i (eq. D52) and
    the rotors' power J w w'."""
    d = constants(with_updates(EHA, eha_torque_limit_n_m=TORQUE_LIMIT_N_M))
    w, integral, u, p1, p2 = 50.0, 2.0, 0.4, 8e6, 5e5
    s = pump_controlled.supply((w, integral, 0.0), u, 0.0, 1.4, 0.0, p1, p2, d)
    motor_torque = EHA.eha_speed_gain_n_m_s_rad * (u * EHA.pump_speed_rad_s - w + integral)
    assert 0.0 < motor_torque < TORQUE_LIMIT_N_M and s.torque == pytest.approx(motor_torque, rel=1e-12)
    pump_torque = pump.shaft_torque_n_m(d.displacement, w, p1 - p2, d.torque_loss)
    j = EHA.eha_motor_inertia_kg_m2
    assert s.speed == w and s.rate == pytest.approx((motor_torque - pump_torque) / j, rel=1e-12)
    assert s.rate2 == pytest.approx((motor_torque / EHA.eha_speed_gain_n_m_s_rad - integral) / 0.05, rel=1e-12)
    assert s.rotor_power == pytest.approx(j * w * s.rate, rel=1e-12)


@pytest.mark.parametrize(("p1", "p2"), [(0.0, 5e5), (8e6, 0.0)])
def test_with_a_cavitation_floor_of_zero_a_line_drawn_to_vacuum_leaves_the_eha_finite(p1, p2):
    """cavitation_pressure_pa may be 0 (its lowest): a line at 0 Pa absolute is a state the
    drive must take, with everything on, as any other."""
    d = constants(with_updates(EHA, cavitation_pressure_pa=0.0, **AS_BUILT))
    s = pump_controlled.supply((60.0, 1.0, 0.0), 0.3, 0.3, 1.4, 0.0, p1, p2, d)
    assert all(math.isfinite(value) for value in s)
    assert s.q_a == pytest.approx(pump_controlled.ports(60.0, 0.3, p1, p2, d).q_a, rel=1e-12)
    assert (s.rate3, s.cylinder, s.force, s.spool) == (0.0, 1.0, 0.0, 0.3)  # through the oil alone


def test_a_pump_that_leaks_nothing_against_the_shut_holding_valve_gives_a_finite_stability_bound():
    """pump_volumetric_efficiency 1 (its highest): G_p = 0, and the pump against the shut valve
    is as stiff as the bound can say, D^2 (1 + c_f) / (J 1e-30), a number the stepping compares
    (too stiff), not a division by zero."""
    d = constants(with_updates(EHA, pump_volumetric_efficiency=1.0, **AS_BUILT))
    assert d.pump_leak == 0.0
    bound = eha_motor.fastest_rate_1_s(2e-2, 5e-3, d, math)
    closed = d.displacement**2 * (1.0 + d.torque_loss) / (EHA.eha_motor_inertia_kg_m2 * 1e-30)
    assert math.isfinite(bound) and bound == pytest.approx(closed, rel=1e-12)
