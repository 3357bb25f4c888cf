"""The fixed pump's supply line (model/drives/fixed_pump.py) at known operating points: its
energy's rate, what an accumulator on it draws, the open centre's pressure in neutral, the
speed on demand the spool sets, and the stability bound's rate against the line's own
(docs/model.md, "Drives", "Open-centre valve", "Motor strategies"; eq. D1, D12-D14, D62, D67)."""

from __future__ import annotations

import math

import pytest

from boom_hydraulics.model import pump, valve
from boom_hydraulics.model.drives import constants, fixed_pump
from boom_hydraulics.model.parameters import Parameters, with_updates

P = Parameters()
D = constants(P)
OPEN = constants(with_updates(P, valve_centre="open"))
LAGGING = constants(with_updates(P, motor_strategy="speed_on_demand"))
P_N, P_T = P.supply_pressure_pa, P.tank_pressure_pa


@pytest.mark.parametrize(("line_pa", "opening", "d"), [(12e6, 0.3, D), (16.5e6, 0.0, D), (9e6, -0.2, LAGGING)])
def test_the_lines_energy_rate_is_the_rate_of_its_compression_and_rotor_energy(line_pa, opening, d):
    """energy_rate is d/dt of energy along the drive's own rates (central difference), with the
    relief open or not and with the motor's speed lagging; at the cavitation floor it is 0."""
    z = (line_pa, 100.0 if d is LAGGING else 0.0, 0.0)
    s = fixed_pump.supply(z, opening, opening, 1.4, 0.0, 7e6, 1e5, d)
    h = 1e-6
    ahead = fixed_pump.energy(tuple(a + h * b for a, b in zip(z, (s.rate, s.rate2, s.rate3))), d)
    behind = fixed_pump.energy(tuple(a - h * b for a, b in zip(z, (s.rate, s.rate2, s.rate3))), d)
    assert fixed_pump.energy_rate(z, s, d) == pytest.approx((ahead - behind) / (2 * h), rel=1e-6)
    assert s.line_oil_work == pytest.approx(d.line_volume * (s.p_supply - P_T) * s.rate / d.bulk_modulus, rel=1e-9)
    void = (P.cavitation_pressure_pa - 1e5, 0.0, 0.0)  # the line cavitating: its pressure at the floor
    s = fixed_pump.supply(void, 1.0, 1.0, 1.4, 0.0, 7e6, 1e5, D)
    assert fixed_pump.energy_rate(void, s, D) == 0.0 and s.p_supply == P.cavitation_pressure_pa
    floor = (P.cavitation_pressure_pa, 0.0, 0.0)  # at the floor itself, drawn from: the void opens, p stands
    s = fixed_pump.supply(floor, 1.0, 1.0, 1.4, 0.0, 7e6, 1e5, D, q_draw=2.0 * P.pump_max_flow_m3_s)
    assert s.rate < 0.0 and fixed_pump.energy_rate(floor, s, D) == 0.0


def test_an_accumulator_on_the_line_draws_its_flow_from_the_lines_oil():
    """q_draw leaves the line: its pressure falls by E / V_s q_draw faster (eq. D13, A3), and the
    power into the line's oil by dp q_draw; below the floor the draw grows the void instead."""
    z = (12e6, 0.0, 0.0)
    base = fixed_pump.supply(z, 0.3, 0.3, 1.4, 0.0, 7e6, 1e5, D)
    drawn = fixed_pump.supply(z, 0.3, 0.3, 1.4, 0.0, 7e6, 1e5, D, q_draw=1e-5)
    assert base.rate - drawn.rate == pytest.approx(P.bulk_modulus_pa / P.supply_line_volume_m3 * 1e-5, rel=1e-9)
    assert base.line_oil_work - drawn.line_oil_work == pytest.approx((12e6 - P_T) * 1e-5, rel=1e-9)
    assert drawn.q_a == base.q_a and drawn.main_relief_loss == base.main_relief_loss


def test_an_open_centre_holds_the_line_at_its_neutral_pressure_drop_and_a_closed_one_at_the_relief():
    """In neutral the open centre passes what the pump delivers, K_c f(dp) = D w_n - G_p dp
    (eq. D67): the line starts there and stays; the closed centre dead-heads at the relief (eq. D14)."""
    start = fixed_pump.initial_state(OPEN)
    dp = start[0] - P_T
    q_centre, _ = valve.centre_flow(0.0, start[0], OPEN)
    assert q_centre == pytest.approx(OPEN.displacement * OPEN.speed - OPEN.pump_leak * dp, rel=1e-9)
    assert 0.9 * P.open_centre_pressure_drop_pa < dp < P.open_centre_pressure_drop_pa  # the leakage's share less
    assert abs(fixed_pump.supply(start, 0.0, 0.0, 1.4, 0.0, 7e6, 1e5, OPEN).rate) < 1e-3 * P.bulk_modulus_pa
    assert fixed_pump.centre_pressure_pa(OPEN.displacement * OPEN.speed, OPEN) == pytest.approx(start[0], rel=1e-12)
    assert fixed_pump.initial_state(D) == (fixed_pump.dead_head_pressure_pa(D), 0.0, 0.0)
    assert fixed_pump.dead_head_pressure_pa(D) > P_N


@pytest.mark.parametrize(("opening", "speed"), [(0.5, 0.5 * P.pump_speed_rad_s), (-0.8, 0.8 * P.pump_speed_rad_s),
                                                (0.1, P.motor_min_speed_rad_s)])  # fmt: skip
def test_speed_on_demand_turns_the_fixed_pump_with_the_spool(opening, speed):
    """eq. D62: the spool sets the speed, |x| w_n, at least w_min; the pump delivers D w - G_p dp (eq. D1)."""
    quick = constants(with_updates(P, motor_strategy="speed_on_demand", motor_time_constant_s=0.0))
    s = fixed_pump.supply((12e6, 0.0, 0.0), opening, opening, 1.4, 0.0, 7e6, 1e5, quick)
    assert s.speed == pytest.approx(speed, rel=1e-12)
    q_pump = quick.displacement * speed - quick.pump_leak * (12e6 - P_T)
    assert s.hydraulic_power == pytest.approx((12e6 - P_T) * q_pump, rel=1e-12)


def test_the_stability_bound_counts_the_relief_where_a_step_can_reach_it_and_the_chamber_behind_the_path():
    """The line's fastest rate rises by the relief's own rate E G_mr / V_s (the change of
    -d(dz/dt)/dz, central difference, as the relief opens) where the line can reach p_n within
    the step at the pump's full flow (exactly there not yet), not further below; and by G E / V for
    the stiffer chamber the open path connects (two oil springs in series), and by the open centre's
    own slope times E / V_s."""
    tight = D._replace(leak=0.0)
    spring = P.bulk_modulus_pa / P.supply_line_volume_m3  # E / V_s, Pa/m^3
    reach = spring * P.pump_max_flow_m3_s * 1e-3  # how far the line rises in a step of 1 ms

    def own(line_pa: float) -> float:
        rate = [fixed_pump.supply((line_pa + h, 0.0, 0.0), 0.0, 0.0, 1.4, 0.0, 7e6, 7e6, tight).rate for h in (1, -1)]
        return -(rate[0] - rate[1]) / 2.0

    def bound(line_pa: float, opening: float = 0.0, stiff1: float = 0.0, stiff2: float = 0.0) -> float:
        return fixed_pump.stiffness((line_pa, 0.0, 0.0), opening, opening, stiff1, stiff2, 1e-3, tight)[2]

    relief = P_N + 0.5 * P.main_relief_range_pa
    assert own(relief) - own(5e6) == pytest.approx(spring * D.g_main, rel=1e-3)
    assert bound(relief) - bound(5e6) == pytest.approx(spring * D.g_main, rel=1e-9) and bound(5e6) >= own(5e6)
    assert bound(P_N - reach + 1e3) == bound(relief) and bound(P_N - reach - 1e3) == bound(5e6)
    assert (P_N - reach) + reach == P_N  # exactly at its reach the relief is not counted, a hair past it is
    assert bound(P_N - reach) == bound(5e6) and bound(math.nextafter(P_N - reach, P_N)) == bound(relief)
    assert bound(5e6) == pytest.approx(spring * D.pump_leak, rel=1e-14)  # closed and tight: E G_p / V_s
    slope = valve.laminar_slope(0.4, tight)
    assert bound(5e6, 0.4, 1e12, 3e12) - bound(5e6, 0.4) == pytest.approx(slope * 3e12, rel=1e-9)
    assert bound(5e6, 0.4, 3e12, 1e12) == bound(5e6, 0.4, 1e12, 3e12)
    centre = valve.centre_slope(0.2, OPEN)  # an open centre not yet closed (|x| < x_c): its own slope too
    with_centre = fixed_pump.stiffness((5e6, 0.0, 0.0), 0.2, 0.2, 0.0, 0.0, 1e-3, OPEN._replace(leak=0.0))[2]
    assert centre > 0.0 and with_centre - bound(5e6, 0.2) == pytest.approx(spring * centre, rel=1e-9)


def test_an_open_valve_takes_its_flow_from_the_line_and_the_pump_gives_it_dp_q():
    """eq. D13: the line's state moves at E / V_s (D w_n - G_p dp - Q_in - Q_mr); the power the
    drive gives the lines is dp Q_in, above tank pressure."""
    z = (12e6, 0.0, 0.0)
    s = fixed_pump.supply(z, 0.3, 0.3, 1.4, 0.0, 7e6, 1e5, D)
    q_in = valve.paths(0.3, 12e6, 7e6, 1e5, D).q_in
    q_pump = D.displacement * D.speed - D.pump_leak * (12e6 - P_T)
    assert q_in > 0.1 * q_pump and fixed_pump.main_relief_flow_m3_s(12e6, D) == 0.0
    assert s.rate == pytest.approx(P.bulk_modulus_pa / P.supply_line_volume_m3 * (q_pump - q_in), rel=1e-12)
    assert s.power == pytest.approx((12e6 - P_T) * q_in, rel=1e-12)


def test_the_pump_is_at_its_flow_limit_below_the_relief_pressure_and_not_from_it():
    """Saturated: the pump gives all it can (the line below p_n, the relief shut); from p_n,
    exactly, the relief takes the rest."""
    for line_pa, saturated in ((math.nextafter(P_N, 0.0), 1.0), (P_N, 0.0), (P_N + 0.5 * P.main_relief_range_pa, 0.0)):
        assert fixed_pump.supply((line_pa, 0.0, 0.0), 0.3, 0.3, 1.4, 0.0, 7e6, 1e5, D).saturated == saturated, line_pa


def test_a_lagging_motors_torque_turns_the_pump_and_speeds_its_rotors():
    """eq. D2, D64: the motor's torque is the pump's shaft torque at its speed plus J dw/dt."""
    z = (12e6, 100.0, 0.0)
    s = fixed_pump.supply(z, 0.5, 0.5, 1.4, 0.0, 7e6, 1e5, LAGGING)
    shaft = pump.shaft_torque_n_m(LAGGING.displacement, 100.0, 12e6 - P_T, LAGGING.torque_loss)
    assert s.rate2 < 0.0 and s.speed == 100.0
    assert s.torque == pytest.approx(shaft + P.motor_rotor_inertia_kg_m2 * s.rate2, rel=1e-12)


def test_the_valve_loss_of_an_open_centre_counts_the_spools_paths_and_the_centre():
    """A spool part open with the centre not yet closed (|x| < x_c) throttles through both (eq. D66)."""
    s = fixed_pump.supply((3e6, 0.0, 0.0), 0.2, 0.2, 1.4, 0.0, 2e6, 1e5, OPEN)
    paths = valve.paths(0.2, 3e6, 2e6, 1e5, OPEN)
    _, centre_loss = valve.centre_flow(0.2, 3e6, OPEN)
    assert paths.throttling > 0.0 and centre_loss > 0.0
    assert s.valve_loss == pytest.approx(paths.throttling + centre_loss, rel=1e-12)
