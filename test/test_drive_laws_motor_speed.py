"""The valve drives' motor strategies (model/drives/motor_speed.py) at known operating points,
each law at its documented limits: the demand's opening, the memory's reset and run-down, the
stop threshold, the speed's clamp and lag, the rotors' torque and energy (docs/model.md,
"Motor strategies", eq. D60-D64). Pure functions of floats: fast interpreted and compiled."""

from __future__ import annotations

import pytest

from boom_hydraulics.model.drives import constants, motor_speed
from boom_hydraulics.model.parameters import Parameters, with_updates

P = Parameters()
CONSTANT = constants(P)
IDLE = constants(with_updates(P, motor_strategy="idle_stop", motor_idle_stop_s=2.0, motor_time_constant_s=0.05))
ON_DEMAND = constants(with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.05))
W_N, W_MIN = P.pump_speed_rad_s, P.motor_min_speed_rad_s


def test_each_strategy_raises_its_own_flag_and_starts_where_it_runs():
    """flags are one-hot in the order of STRATEGIES; idle_stop starts at w_n having just had
    demand (m = 1), speed_on_demand at w_min, the constant motor's states stand at 0."""
    assert motor_speed.STRATEGIES == ("constant", "idle_stop", "speed_on_demand")
    assert motor_speed.flags(CONSTANT) == (1.0, 0.0, 0.0)
    assert motor_speed.flags(IDLE) == (0.0, 1.0, 0.0)
    assert motor_speed.flags(ON_DEMAND) == (0.0, 0.0, 1.0)
    assert motor_speed.initial_state(CONSTANT) == (0.0, 0.0)
    assert motor_speed.initial_state(IDLE) == (W_N, 1.0)
    assert motor_speed.initial_state(ON_DEMAND) == (W_MIN, 0.0)


@pytest.mark.parametrize(
    ("opening", "expected"),
    [(0.0, 0.0), (0.01, 0.5), (-0.01, 0.5), (0.02, 1.0), (-0.02, 1.0), (0.5, 1.0), (0.005, 0.15625)],
)
def test_the_valves_demand_rises_smoothly_from_neutral_to_full_at_2_percent_of_the_stroke(opening, expected):
    """w_d = smoothstep(|x| / 0.02) (eq. D60): half at 1 %, full from 2 % either way."""
    assert motor_speed.DEMAND_OPENING == 0.02
    assert motor_speed.demand(opening) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_the_demand_memory_jumps_back_on_demand_and_runs_down_over_the_idle_time():
    """m' = w_d (1 - m) / tau_r - (1 - w_d) min(m / M_STOP, 1) / T_idle (eq. D60): back to 1
    within 10 ms on demand, down by 1 / T_idle without it, slowing below M_STOP, still at 0."""
    assert (motor_speed.MEMORY_RESET_S, motor_speed.M_STOP) == (0.01, 0.01)
    assert motor_speed.memory_rate(0.4, 0.3, IDLE) == pytest.approx(0.6 / 0.01, rel=1e-12)
    assert motor_speed.memory_rate(1.0, -0.3, IDLE) == 0.0
    assert motor_speed.memory_rate(0.4, 0.0, IDLE) == pytest.approx(-1.0 / 2.0, rel=1e-12)
    assert motor_speed.memory_rate(0.01, 0.0, IDLE) == pytest.approx(-1.0 / 2.0, rel=1e-12)  # at M_STOP
    assert motor_speed.memory_rate(0.005, 0.0, IDLE) == pytest.approx(-0.5 / 2.0, rel=1e-12)  # below it
    assert motor_speed.memory_rate(-0.001, 0.0, IDLE) == 0.0
    half = 0.5 * (1.0 - 0.4) / 0.01 - 0.5 * 1.0 / 2.0  # at 1 % opening the demand is 1/2
    assert motor_speed.memory_rate(0.4, 0.01, IDLE) == pytest.approx(half, rel=1e-12)


@pytest.mark.parametrize(("memory", "expected"), [(1.0, 1.0), (0.01, 1.0), (0.005, 0.5), (0.0, 0.0), (-0.5, 0.0)])
def test_idle_stop_runs_the_motor_until_its_memory_has_run_down_to_m_stop(memory, expected):
    """running = smoothstep(m / M_STOP) (eq. D61), and the target speed w_n times it."""
    assert motor_speed.running(memory) == pytest.approx(expected, rel=1e-12)
    target = motor_speed.target_speed_rad_s((0.0, 0.0, memory), 500.0, IDLE)
    assert target == pytest.approx(W_N * expected, rel=1e-12)


@pytest.mark.parametrize(("required", "expected"), [(100.0, 100.0), (10.0, W_MIN), (1e4, W_N), (W_MIN, W_MIN)])
def test_speed_on_demand_heads_for_the_required_speed_between_w_min_and_w_n(required, expected):
    """eq. D62: min(max(required, w_min), w_n); the constant motor heads for w_n whatever is required."""
    assert motor_speed.target_speed_rad_s((0.0, 0.0, 0.0), required, ON_DEMAND) == pytest.approx(expected, rel=1e-12)
    assert motor_speed.target_speed_rad_s((0.0, 0.0, 0.0), required, CONSTANT) == W_N


def test_the_motor_lags_its_target_and_its_rotors_take_torque_and_store_energy():
    """eq. D63, D64 at w = 80 rad/s heading for 100: w' = (100 - 80) / tau, T = J w',
    P_rot = T w = d/dt (J w^2 / 2); the constant motor turns at w_n with no rate at all."""
    tau, inertia = 0.05, P.motor_rotor_inertia_kg_m2
    m = motor_speed.motor((0.0, 80.0, 0.0), 0.3, 100.0, ON_DEMAND)
    assert m.speed == 80.0 and m.speed_rate == pytest.approx(20.0 / tau, rel=1e-12) and m.memory_rate == 0.0
    assert m.torque == pytest.approx(inertia * 20.0 / tau, rel=1e-12)
    assert m.rotor_power == pytest.approx(m.torque * 80.0, rel=1e-12)
    assert motor_speed.energy((0.0, 80.0, 0.0), ON_DEMAND) == pytest.approx(0.5 * inertia * 80.0**2, rel=1e-12)
    assert motor_speed.energy_rate((0.0, 80.0, 0.0), m.speed_rate, ON_DEMAND) == pytest.approx(m.rotor_power)
    fixed = motor_speed.motor((0.0, 80.0, 0.7), 0.3, 100.0, CONSTANT)
    assert tuple(fixed) == (W_N, 0.0, 0.0, 0.0, 0.0)
    idle = motor_speed.motor((0.0, 80.0, 0.4), 0.0, 0.0, IDLE)  # running, no demand: the memory runs down
    assert idle.memory_rate == pytest.approx(-1.0 / 2.0) and idle.speed_rate == pytest.approx((W_N - 80.0) / tau)
    # on demand the memory (the third state, not the speed) heads back to 1 within tau_r (eq. D60)
    asked = motor_speed.motor((0.0, 80.0, 0.4), 0.3, 100.0, IDLE)
    assert asked.memory_rate == pytest.approx((1.0 - 0.4) / motor_speed.MEMORY_RESET_S, rel=1e-12)


def test_without_a_lag_the_motor_is_at_its_target_and_neither_takes_torque_nor_stores_energy():
    """motor_time_constant_s = 0: the speed is the target at once (eq. D63), J w' is 0."""
    quick = constants(with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.0))
    m = motor_speed.motor((0.0, 80.0, 0.0), 0.3, 100.0, quick)
    assert (m.speed, m.speed_rate, m.torque, m.rotor_power) == (100.0, 0.0, 0.0, 0.0)
    assert motor_speed.energy((0.0, 80.0, 0.0), quick) == 0.0
    assert motor_speed.energy_rate((0.0, 80.0, 0.0), m.speed_rate, quick) == 0.0
    assert motor_speed.fastest_rate(quick) == 0.0


def test_a_heavy_rotors_energy_rate_is_its_kinetic_power():
    """J w w' for rotors of 2.5 kg m^2 (a large machine and pump, within the parameter's range):
    the rate of J w^2 / 2 along w' = (100 - 80) / tau (eq. D64)."""
    heavy = constants(
        with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.05, motor_rotor_inertia_kg_m2=2.5)
    )
    m = motor_speed.motor((0.0, 80.0, 0.0), 0.3, 100.0, heavy)
    rate = motor_speed.energy_rate((0.0, 80.0, 0.0), m.speed_rate, heavy)
    assert rate == pytest.approx(2.5 * 80.0 * 20.0 / 0.05, rel=1e-12)
    assert rate == pytest.approx(m.rotor_power, rel=1e-12)


def test_the_fastest_rate_is_the_speeds_lag_and_idle_stops_memory_reset():
    assert motor_speed.fastest_rate(CONSTANT) == 0.0
    assert motor_speed.fastest_rate(ON_DEMAND) == pytest.approx(1.0 / 0.05, rel=1e-12)
    assert motor_speed.fastest_rate(IDLE) == pytest.approx(1.0 / 0.05 + 1.0 / 0.01, rel=1e-12)
