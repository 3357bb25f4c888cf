"""The hydraulic elements' laws (model/hydraulics.py) at operating points worked out by hand:
each value follows from the equation docs/model.md gives ("Chambers", "Orifices and the 4/3
valve", "Supply and relief valves"), with a tolerance far tighter than a wrong term's effect,
and each documented switch exactly at its limit and one past it. Pure Python (xp=math) and
numpy arrays (the batch runs), no simulation: the whole file runs in well under a second."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import hydraulics as h

TIGHT = 1e-12

# an operating point of a typical 4/3 valve: 0.7 discharge, 1 cm^2 path, mineral oil
RHO = 850.0
K = 0.7 * 1e-4 * math.sqrt(2.0 / RHO)  # eq. 14: mu f sqrt(2 / rho)
P_TR = 2.0e5  # laminar-turbulent transition, Pa
TR2 = P_TR * P_TR


def test_pos_smaller_larger_are_max_and_min_on_floats_and_arrays() -> None:
    assert h.pos(2.5) == 2.5
    assert h.pos(-3.0) == 0.0
    assert h.pos(0.0) == 0.0
    assert h.smaller(3.0, 5.0) == 3.0
    assert h.smaller(5.0, 3.0) == 3.0
    assert h.smaller(2.0, 1e300) == 2.0  # exact also when y is huge
    assert h.smaller(-7.0, -7.0) == -7.0
    assert h.larger(3.0, 5.0) == 5.0
    assert h.larger(5.0, 3.0) == 5.0
    z = np.array([-2.0, 0.0, 1.5])
    assert np.array_equal(h.pos(z), [0.0, 0.0, 1.5])
    assert np.array_equal(h.smaller(z, np.array([1.0, -1.0, 1.0])), [-2.0, -1.0, 1.0])
    assert np.array_equal(h.larger(z, np.array([1.0, -1.0, 1.0])), [1.0, 0.0, 1.5])


def test_smoothstep_is_0_up_to_0_and_1_from_1_with_the_cubic_between() -> None:
    assert h.smoothstep(-0.5) == 0.0
    assert h.smoothstep(0.0) == 0.0
    assert h.smoothstep(0.25) == pytest.approx(3 / 16 - 2 / 64, rel=TIGHT, abs=0.0)
    assert h.smoothstep(0.5) == pytest.approx(0.5, rel=TIGHT, abs=0.0)
    assert h.smoothstep(1.0) == 1.0
    assert h.smoothstep(1.5) == 1.0  # one past the end: held at 1
    assert np.allclose(h.smoothstep(np.array([-1.0, 0.75, 2.0])), [0.0, 27 / 16 - 54 / 64, 1.0], rtol=TIGHT)


def test_orifice_coefficient_is_mu_f_sqrt_2_over_rho() -> None:
    # eq. 14: 0.7 * 1 cm^2 * sqrt(2 / 850 kg/m^3)
    assert h.orifice_coefficient(0.7, 1e-4, RHO) == pytest.approx(0.7e-4 * 0.048507125007266595, rel=TIGHT, abs=0.0)
    assert h.orifice_coefficient(0.6, 2e-4, 800.0) == pytest.approx(1.2e-4 * 0.05, rel=TIGHT, abs=0.0)


def test_turbulent_orifice_passes_k_sqrt_dp_with_the_sign_of_dp() -> None:
    assert h.turbulent_orifice_flow(K, 1e6) == pytest.approx(K * 1000.0, rel=TIGHT, abs=0.0)
    assert h.turbulent_orifice_flow(K, -4e6) == pytest.approx(-K * 2000.0, rel=TIGHT, abs=0.0)
    assert h.turbulent_orifice_flow(K, 0.0) == 0.0


def test_orifice_flow_is_laminar_below_the_transition_turbulent_above_and_odd() -> None:
    # at dp = p_tr: K p_tr / (2 p_tr^2)^(1/4) = K sqrt(p_tr) / 2^(1/4)
    assert h.orifice_flow(K, P_TR, TR2) == pytest.approx(K * math.sqrt(P_TR) / 2**0.25, rel=TIGHT, abs=0.0)
    assert h.orifice_flow(K, -P_TR, TR2) == pytest.approx(-K * math.sqrt(P_TR) / 2**0.25, rel=TIGHT, abs=0.0)
    # at dp = 3/4 p_tr: (p_tr^2 (9/16 + 1))^(1/4) = sqrt(p_tr) (25/16)^(1/4) = sqrt(p_tr) sqrt(5/4)
    dp = 0.75 * P_TR
    assert h.orifice_flow(K, dp, TR2) == pytest.approx(K * dp / (math.sqrt(P_TR) * math.sqrt(1.25)), rel=TIGHT, abs=0.0)
    # laminar far below the transition, turbulent far above (docstring's limits)
    assert h.orifice_flow(K, 10.0, TR2) == pytest.approx(K * 10.0 / math.sqrt(P_TR), rel=1e-8, abs=0.0)
    assert h.orifice_flow(K, 2e9, TR2) == pytest.approx(h.turbulent_orifice_flow(K, 2e9), rel=1e-8, abs=0.0)
    assert h.orifice_flow(K, 0.0, TR2) == 0.0
    flows = h.orifice_flow(K, np.array([-P_TR, 0.0, P_TR]), TR2, np)
    assert np.allclose(flows, [-1.0, 0.0, 1.0] * np.array(K * math.sqrt(P_TR) / 2**0.25), rtol=TIGHT)


@pytest.mark.parametrize("dp", [1e3, P_TR, 7.5e5, 2.1e7])
def test_orifice_pressure_drop_inverts_the_orifice_flow(dp: float) -> None:
    flow = h.orifice_flow(K, dp, TR2)
    assert h.orifice_pressure_drop(K, flow, TR2) == pytest.approx(dp, rel=1e-9, abs=0.0)
    assert h.orifice_pressure_drop(K, np.array([flow]), TR2, np)[0] == pytest.approx(dp, rel=1e-9, abs=0.0)


def test_orifice_pressure_drop_at_the_transition() -> None:
    # the flow K sqrt(p_tr) / 2^(1/4) needs exactly dp = p_tr
    assert h.orifice_pressure_drop(K, K * math.sqrt(P_TR) / 2**0.25, TR2) == pytest.approx(P_TR, rel=TIGHT, abs=0.0)


def test_chamber_pressure_rate_is_e_over_v_times_net_inflow() -> None:
    # eq. 12: 1.5 GPa / 1 l * (0.2 l/s in - 0.05 l/s of growth) = 2.25e8 Pa/s
    assert h.chamber_pressure_rate(1.5e9, 1e-3, 2e-4, 5e-5) == pytest.approx(2.25e8, rel=TIGHT, abs=0.0)
    assert h.chamber_pressure_rate(1.5e9, 2e-3, 0.0, 4e-4) == pytest.approx(-3.0e8, rel=TIGHT, abs=0.0)


def test_a_chamber_pressure_is_its_state_down_to_the_floor_and_the_floor_below() -> None:
    floor = 3e3
    assert h.chamber_pressure_pa(5e6, floor) == 5e6
    assert h.chamber_pressure_pa(floor, floor) == floor  # exactly at the floor
    assert h.chamber_pressure_pa(floor - 1.0, floor) == floor  # one past: held
    assert h.chamber_pressure_pa(-2e6, floor) == floor


def test_a_full_chamber_rates_as_eq_12_and_a_cavitating_one_takes_the_difference_in_its_void() -> None:
    e, v, floor = 1.5e9, 1e-3, 3e3
    # full of liquid: eq. 12 alone
    assert h.chamber_state_rate(e, v, 2e-4, 5e-5, 1e6, floor) == pytest.approx(2.25e8, rel=TIGHT, abs=0.0)
    assert h.chamber_state_rate(e, v, 2e-4, 5e-5, floor, floor) == pytest.approx(2.25e8, rel=TIGHT, abs=0.0)
    # a void of (p_cav - z) V / E = 1e6 Pa * 1 l / 1.5 GPa, growing as the chamber grows:
    # dz/dt = E/V (Q - dV/dt) + (p_cav - z) dV/dt / V = 2.25e8 + 1e6 * 5e-5 / 1e-3 = 2.25e8 + 5e4
    z = floor - 1e6
    assert h.chamber_state_rate(e, v, 2e-4, 5e-5, z, floor) == pytest.approx(2.25e8 + 5e4, rel=TIGHT, abs=0.0)
    assert h.void_volume_m3(e, v, z, floor) == pytest.approx(1e6 * 1e-3 / 1.5e9, rel=TIGHT, abs=0.0)
    assert h.void_volume_m3(e, v, floor, floor) == 0.0
    assert h.void_volume_m3(e, v, floor + 1.0, floor) == 0.0


def test_the_void_keeps_oil_it_neither_makes_nor_loses() -> None:
    """With no inflow, a growing chamber's void grows by exactly the chamber's growth:
    d(V_void)/dt = dV/dt (from z and V moved along their rates)."""
    e, v, floor, dv_dt = 1.5e9, 1e-3, 3e3, 2e-5
    z = floor - 4e5
    dt = 1e-6
    rate = h.chamber_state_rate(e, v, 0.0, dv_dt, z, floor)
    grown = h.void_volume_m3(e, v + dv_dt * dt, z + rate * dt, floor) - h.void_volume_m3(e, v, z, floor)
    assert grown / dt == pytest.approx(dv_dt, rel=1e-4, abs=0.0)


def test_a_load_holding_valve_passes_inflow_checks_outflow_by_its_pilot_and_its_seat_leaks() -> None:
    seat, p, tank = 1e-13, 1.0e7, 1e5
    leak = seat * (p - tank)
    assert h.load_holding_flow(1e-4, 0.3, p, tank, seat) == pytest.approx(1e-4 - leak, rel=TIGHT, abs=0.0)
    assert h.load_holding_flow(-1e-4, 0.3, p, tank, seat) == pytest.approx(-0.3e-4 - leak, rel=TIGHT, abs=0.0)
    assert h.load_holding_flow(-1e-4, 0.0, p, tank, seat) == pytest.approx(-leak, rel=TIGHT, abs=0.0)  # sealed
    assert h.load_holding_flow(-1e-4, 1.0, p, tank, 0.0) == pytest.approx(-1e-4, rel=TIGHT, abs=0.0)  # open


def test_a_relief_valve_opens_one_pascal_past_cracking_and_passes_its_rated_flow_at_the_range() -> None:
    crack, rated, width = 2.0e7, 1e-3, 2.0e6
    g = rated / width
    assert h.relief_flow(crack - 1.0, crack, g) == 0.0
    assert h.relief_flow(crack, crack, g) == 0.0  # exactly at cracking
    assert h.relief_flow(crack + 1.0, crack, g) == pytest.approx(g, rel=1e-6, abs=0.0)  # one past
    assert h.relief_flow(crack + width, crack, g) == pytest.approx(rated, rel=TIGHT, abs=0.0)


PS, PT, P1, P2 = 2.0e7, 1.0e5, 8.0e6, 3.0e6  # supply, tank, piston side, rod side
LEAK = 1e-13


def _orifice(dp: float) -> float:
    return dp / (dp * dp + TR2) ** 0.25


@pytest.mark.parametrize("opening", [0.5, -0.5, 1.0, -0.2])
def test_the_4_3_valve_opens_p_a_and_b_t_forward_p_b_and_a_t_back_each_with_its_leak(opening: float) -> None:
    q_pa, q_at, q_pb, q_bt = h.valve_flows(opening, PS, PT, P1, P2, K, TR2, LEAK)
    fwd, back = max(opening, 0.0), max(-opening, 0.0)
    assert q_pa == pytest.approx(K * fwd * _orifice(PS - P1) + LEAK * (PS - P1), rel=TIGHT, abs=0.0)
    assert q_at == pytest.approx(K * back * _orifice(P1 - PT) + LEAK * (P1 - PT), rel=TIGHT, abs=0.0)
    assert q_pb == pytest.approx(K * back * _orifice(PS - P2) + LEAK * (PS - P2), rel=TIGHT, abs=0.0)
    assert q_bt == pytest.approx(K * fwd * _orifice(P2 - PT) + LEAK * (P2 - PT), rel=TIGHT, abs=0.0)


def test_a_centred_valve_only_leaks_and_its_flows_follow_the_sign_of_their_pressure_drop() -> None:
    q = h.valve_flows(0.0, PS, PT, P1, P2, K, TR2, LEAK)
    assert q == pytest.approx(
        (LEAK * (PS - P1), LEAK * (P1 - PT), LEAK * (PS - P2), LEAK * (P2 - PT)), rel=TIGHT, abs=0.0
    )
    # A above the supply: P->A runs backwards, out of A into P
    q_pa = h.valve_flows(0.5, PS, PT, PS + 1e6, P2, K, TR2, 0.0)[0]
    assert q_pa == pytest.approx(-0.5 * K * _orifice(1e6), rel=TIGHT, abs=0.0)
    arrays = h.valve_flows(np.array([0.5, -0.5]), PS, PT, P1, P2, K, TR2, LEAK, np)
    assert arrays[0][0] == pytest.approx(K * 0.5 * _orifice(PS - P1) + LEAK * (PS - P1), rel=TIGHT, abs=0.0)
    assert arrays[2][1] == pytest.approx(K * 0.5 * _orifice(PS - P2) + LEAK * (PS - P2), rel=TIGHT, abs=0.0)


def test_the_supply_holds_its_setting_while_the_pump_keeps_up() -> None:
    assert h.supply_pressure(0.0, PS, P1, P2, K, TR2, 1e-3) == PS  # centred: the pump holds p_set
    assert h.supply_pressure(0.1, PS, P1, P2, K, TR2, 1e-2) == PS  # 1.2 l/s through 10 %: < Q_max
    assert h.supply_pressure(-0.1, PS, P1, P2, K, TR2, 1e-2) == PS


@pytest.mark.parametrize("opening", [1.0, 0.5, -0.5, -1.0])
@pytest.mark.parametrize(("p1", "p2"), [(P1, P2), (7_654_321.3, 2_345_678.7)])  # round, and as a run gives them
def test_the_supply_falls_to_the_pressure_at_which_the_open_path_takes_the_pump_maximum(
    opening: float, p1: float, p2: float
) -> None:
    q_max = 2e-4  # less than the path takes at p_set
    fed = p1 if opening > 0 else p2
    p = h.supply_pressure(opening, PS, p1, p2, K, TR2, q_max)
    assert p < PS
    assert K * abs(opening) * _orifice(p - fed) == pytest.approx(q_max, rel=1e-9, abs=0.0)
    p_arr = h.supply_pressure(np.array([opening, 0.0]), PS, p1, p2, K, TR2, q_max, np)
    assert p_arr[0] == pytest.approx(p, rel=TIGHT, abs=0.0)
    assert p_arr[1] == PS
