"""The 4/3 valve with its load-holding valve and open centre (model/valve.py) at operating points
worked out by hand (docs/model.md, "Valve", "Open-centre valve", "Supply and relief valves"):
what reaches the cylinder lines, how far the pilot opens the load-holding valve (exactly at its
full opening and one past), and the energy balance the ledger relies on (eq. D27): what the
valve dissipates is what the pump delivers less what reaches the lines. Pure Python, no
simulation."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from boom_hydraulics.model import hydraulics, valve

TIGHT = 1e-12
K = 3.4e-6  # K of a fully open path, m^3/(s Pa^0.5)
P_TR = 2.0e5
PS, PT, P1, P2 = 2.0e7, 1.0e5, 8.0e6, 3.0e6  # P port, tank, piston side, rod side


def drive(holding: float = 1.0, leak: float = 1e-13, seat_leak: float = 4e-14, **centre: float) -> SimpleNamespace:
    """The drives' constants the valve reads (model/drives/constants.py)."""
    d = SimpleNamespace(
        k_valve=K,
        transition2=P_TR * P_TR,
        k_laminar=K / math.sqrt(P_TR),
        leak=leak,
        holding=holding,
        seat_leak=seat_leak,
        p_tank=PT,
        open_centre=1.0,
        k_centre=2.0e-6,
        centre_closed=0.2,
    )
    d.__dict__.update(centre)
    return d


def spool(opening: float, d: SimpleNamespace, p1: float = P1) -> tuple[float, float, float, float]:
    return hydraulics.valve_flows(opening, PS, PT, p1, P2, K, P_TR * P_TR, d.leak)


def balance(v: valve.Paths, p1: float = P1) -> float:
    """What the P port delivers less what the lines take, all above tank pressure, W."""
    return (PS - PT) * v.q_in - (p1 - PT) * v.q_a - (P2 - PT) * v.q_b


# (opening, piston-side pressure): raising, centred, lowering part-piloted, fully and past
OPERATING = [(0.6, P1), (0.0, P1), (0.0, 1.5e7), (-0.0125, P1), (-0.025, P1), (-0.05, P1), (-0.4, P1)]


@pytest.mark.parametrize(("opening", "p1"), OPERATING)
@pytest.mark.parametrize("holding", [1.0, 0.0])
def test_what_the_valve_dissipates_is_what_the_pump_delivers_less_what_reaches_the_lines(
    opening: float, p1: float, holding: float
) -> None:
    v = valve.paths(opening, PS, p1, P2, drive(holding))
    assert v.throttling + v.leakage == pytest.approx(balance(v, p1), rel=1e-10, abs=0.0)
    assert v.throttling >= -1e-12 * v.leakage  # none but rounding where only leakage flows
    assert v.leakage > 0.0


def test_raising_feeds_a_through_the_check_and_drains_b() -> None:
    d = drive()
    q_pa, q_at, q_pb, q_bt = spool(0.6, d)
    v = valve.paths(0.6, PS, P1, P2, d)
    seat = d.seat_leak * (P1 - PT)
    assert v.q_a == pytest.approx(q_pa - q_at - seat, rel=TIGHT, abs=0.0)
    assert v.q_b == pytest.approx(q_pb - q_bt, rel=TIGHT, abs=0.0)
    assert v.q_in == pytest.approx(q_pa + q_pb, rel=TIGHT, abs=0.0)
    assert v.leakage == pytest.approx(
        d.leak * ((PS - P1) ** 2 + (P1 - PT) ** 2 + (PS - P2) ** 2 + (P2 - PT) ** 2) + d.seat_leak * (P1 - PT) ** 2,
        rel=TIGHT,
    )
    assert v.throttling == pytest.approx(
        (PS - P1) * q_pa + (P1 - PT) * q_at + (PS - P2) * q_pb + (P2 - PT) * q_bt - v.leakage + seat * (P1 - PT),
        rel=TIGHT,
    )


# spool opening towards lowering -> pilot opening: smoothstep of x / 0.05 (valve.PILOT_FULL_OPENING)
PILOT = [(0.0, 0.0), (-0.0125, 3 / 16 - 2 / 64), (-0.025, 0.5), (-0.05, 1.0), (-0.06, 1.0), (-0.5, 1.0)]


@pytest.mark.parametrize(("opening", "pilot"), PILOT)
def test_lowering_pilots_the_load_holding_valve_open_smoothly_until_5_percent(opening: float, pilot: float) -> None:
    d = drive()
    q_pa, q_at, q_pb, q_bt = spool(opening, d, p1=1.5e7)  # a heavy load: oil leaves A
    assert q_pa - q_at < 0.0
    v = valve.paths(opening, PS, 1.5e7, P2, d)
    seat = d.seat_leak * (1.5e7 - PT)
    assert v.q_a == pytest.approx(pilot * (q_pa - q_at) - seat, rel=TIGHT, abs=0.0)
    assert v.q_in == pytest.approx(pilot * q_pa + q_pb, rel=TIGHT, abs=0.0)
    assert v.q_b == pytest.approx(q_pb - q_bt, rel=TIGHT, abs=0.0)
    dp_pa, dp_at = PS - 1.5e7, 1.5e7 - PT
    assert v.leakage == pytest.approx(
        d.leak * (pilot * (dp_pa**2 + dp_at**2) + (PS - P2) ** 2 + (P2 - PT) ** 2) + d.seat_leak * dp_at**2, rel=TIGHT
    )


def test_the_pilot_is_fully_open_exactly_at_its_documented_opening() -> None:
    assert valve.PILOT_FULL_OPENING == 0.05


def test_without_a_load_holding_valve_a_passes_both_ways_and_nothing_leaks_through_a_seat() -> None:
    d = drive(holding=0.0)
    for opening in (0.0, -0.0125, -0.4):
        q_pa, q_at, _, _ = spool(opening, d, p1=1.5e7)
        v = valve.paths(opening, PS, 1.5e7, P2, d)
        assert v.q_a == pytest.approx(q_pa - q_at, rel=TIGHT, abs=0.0)
        dp_pa, dp_at = PS - 1.5e7, 1.5e7 - PT
        assert v.leakage == pytest.approx(
            d.leak * (dp_pa**2 + dp_at**2 + (PS - P2) ** 2 + (P2 - PT) ** 2), rel=TIGHT, abs=0.0
        )


def test_a_closed_load_holding_valve_holds_the_load_but_for_its_seat() -> None:
    d = drive(leak=0.0)
    v = valve.paths(0.0, PS, 1.5e7, P2, d)
    assert v.q_a == pytest.approx(-d.seat_leak * (1.5e7 - PT), rel=TIGHT, abs=0.0)
    assert v.leakage == pytest.approx(d.seat_leak * (1.5e7 - PT) ** 2, rel=TIGHT, abs=0.0)
    assert v.throttling == pytest.approx(0.0, abs=1e-9)


def test_valve_paths_run_on_arrays_as_on_floats() -> None:
    d = drive()
    openings = np.array([0.6, -0.025, 0.0])
    arrays = valve.paths(openings, PS, P1, P2, d, np)
    for i, opening in enumerate(openings):
        one = valve.paths(float(opening), PS, P1, P2, d)
        for got, want in zip(arrays, one, strict=True):
            assert got[i] == pytest.approx(want, rel=TIGHT, abs=0.0)


def test_laminar_slope_is_the_open_paths_laminar_slope_plus_two_leaks() -> None:
    d = drive()
    assert valve.laminar_slope(0.5, d) == pytest.approx(0.5 * K / math.sqrt(P_TR) + 2e-13, rel=TIGHT, abs=0.0)
    # it is the slope of the flow into A at equal pressures: P->A's K x / sqrt(p_tr) + G, A->T's G
    dp = 1.0
    q = [valve.paths(0.5, PS, PS + s * dp, P2, drive(holding=0.0)).q_a for s in (-1.0, 1.0)]
    assert (q[0] - q[1]) / (2 * dp) == pytest.approx(valve.laminar_slope(0.5, d), rel=1e-6, abs=0.0)


@pytest.mark.parametrize(("flow", "drop"), [(1e-3, 5e5), (2.5e-4, 1e5), (1e-3, P_TR)])
def test_an_open_centre_passes_the_flow_it_is_sized_for_at_its_pressure_drop(flow: float, drop: float) -> None:
    k_c = valve.centre_coefficient(flow, drop, P_TR)
    assert hydraulics.orifice_flow(k_c, drop, P_TR * P_TR) == pytest.approx(flow, rel=TIGHT, abs=0.0)
    d = drive(k_centre=k_c)
    q, loss = valve.centre_flow(0.0, PT + drop, d)
    assert q == pytest.approx(flow, rel=TIGHT, abs=0.0)
    assert loss == pytest.approx(drop * flow, rel=TIGHT, abs=0.0)


# spool opening -> the open centre's share of its area: 1 - |x| / x_c down to 0 at x_c = 0.2
CENTRE = [(0.0, 1.0), (0.05, 0.75), (-0.1, 0.5), (0.2, 0.0), (-0.2, 0.0), (0.21, 0.0), (-0.9, 0.0)]


@pytest.mark.parametrize(("opening", "share"), CENTRE)
def test_the_open_centre_closes_linearly_until_its_closing_opening(opening: float, share: float) -> None:
    d = drive()
    assert valve.centre_opening(opening, d) == pytest.approx(share, rel=TIGHT, abs=1e-15)
    q, loss = valve.centre_flow(opening, PT + 5e5, d)
    assert q == pytest.approx(share * d.k_centre * hydraulics.orifice_flow(1.0, 5e5, P_TR * P_TR), rel=TIGHT, abs=1e-18)
    assert loss == pytest.approx(5e5 * q, rel=TIGHT, abs=1e-12)
    assert valve.centre_slope(opening, d) == pytest.approx(share * d.k_centre / math.sqrt(P_TR), rel=TIGHT, abs=1e-18)


def test_a_closed_centre_passes_nothing() -> None:
    d = drive(open_centre=0.0)
    assert valve.centre_flow(0.0, PT + 5e5, d) == (0.0, 0.0)
    assert valve.centre_slope(0.0, d) == 0.0


def test_the_centre_slope_is_the_centre_flow_s_slope_at_equal_pressures() -> None:
    d = drive()
    dp = 1.0
    slope = (valve.centre_flow(0.05, PT + dp, d)[0] - valve.centre_flow(0.05, PT - dp, d)[0]) / (2 * dp)
    assert slope == pytest.approx(valve.centre_slope(0.05, d), rel=1e-6, abs=0.0)
    arrays = valve.centre_flow(np.array([0.05, -0.1]), PT + 5e5, d, np)
    assert arrays[0][1] == pytest.approx(valve.centre_flow(-0.1, PT + 5e5, d)[0], rel=TIGHT, abs=0.0)
