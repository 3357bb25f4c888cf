"""The battery's element laws (docs/model.md, "Battery", eq. D8-D11) at operating points their
equations fix: the current that gives the terminal power, both ways, without and beyond the
internal resistance's limit; its heat, chemical power and state of charge; the overload flag
exactly at the most the battery can give and one past it; each also on a batch (xp=numpy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from boom_hydraulics.model import battery

#: A 48 V pack with 0.25 ohm: it gives at most U^2 / (4 R) = 2304 W, exactly in floats.
VOLTAGE_V, RESISTANCE_OHM, LIMIT_W = 48.0, 0.25, 2304.0


def test_the_current_is_the_root_of_the_terminal_power_nearer_zero_both_ways():
    for power_w in (1500.0, -900.0, 37.5):
        current = battery.battery_current_a(power_w, VOLTAGE_V, RESISTANCE_OHM)
        assert VOLTAGE_V * current - RESISTANCE_OHM * current * current == pytest.approx(power_w, rel=1e-12)  # D8
        assert abs(current) < VOLTAGE_V / (2.0 * RESISTANCE_OHM)  # the root nearer zero
        assert math.copysign(1.0, current) == math.copysign(1.0, power_w)  # I > 0 discharges
    assert battery.battery_current_a(1500.0, VOLTAGE_V, 0.0) == 1500.0 / VOLTAGE_V  # R = 0: P / U
    # at the limit the two roots meet, U / (2 R); beyond it the root is taken at the limit's root term
    assert battery.battery_current_a(LIMIT_W, VOLTAGE_V, RESISTANCE_OHM) == VOLTAGE_V / (2.0 * RESISTANCE_OHM)
    assert battery.battery_current_a(3000.0, VOLTAGE_V, RESISTANCE_OHM) == 2.0 * 3000.0 / VOLTAGE_V
    currents = battery.battery_current_a(np.array([1500.0, -900.0]), VOLTAGE_V, RESISTANCE_OHM, np)
    np.testing.assert_allclose(
        currents, [battery.battery_current_a(p, VOLTAGE_V, RESISTANCE_OHM) for p in (1500.0, -900.0)], rtol=1e-15
    )


def test_the_heat_chemical_power_and_state_of_charge_follow_their_definitions():
    current = battery.battery_current_a(1500.0, VOLTAGE_V, RESISTANCE_OHM)
    heat = battery.battery_loss_w(current, RESISTANCE_OHM)
    assert heat == pytest.approx(RESISTANCE_OHM * current**2, rel=1e-15)  # D9
    assert battery.battery_loss_w(-current, RESISTANCE_OHM) == heat  # charging heats it as much
    assert battery.chemical_power_w(current, VOLTAGE_V) == pytest.approx(1500.0 + heat, rel=1e-12)  # D9
    assert battery.chemical_power_w(-3.0, VOLTAGE_V) == -144.0  # charging: the store takes power
    capacity_j = 2.5 * battery.J_PER_KWH
    assert battery.J_PER_KWH == 3600.0 * 1000.0
    assert battery.state_of_charge_rate_1_s(current, VOLTAGE_V, capacity_j) == pytest.approx(
        -VOLTAGE_V * current / capacity_j, rel=1e-15
    )  # D10: discharging lowers it
    assert battery.state_of_charge_rate_1_s(-3.0, VOLTAGE_V, capacity_j) > 0.0
    assert battery.state_of_charge(0.8, 0.3 * capacity_j, 0.1 * capacity_j, capacity_j) == pytest.approx(0.6)
    assert battery.state_of_charge(0.5, 0.0, 0.2 * capacity_j, capacity_j) == pytest.approx(0.7)


def test_the_battery_is_overloaded_one_past_the_most_it_can_give_not_at_it():
    assert battery.overloaded(LIMIT_W, VOLTAGE_V, RESISTANCE_OHM) == 0.0  # D11, exactly at the limit
    assert battery.overloaded(LIMIT_W * (1.0 + 1e-12), VOLTAGE_V, RESISTANCE_OHM) == 1.0
    assert battery.overloaded(-1e6, VOLTAGE_V, RESISTANCE_OHM) == 0.0  # charging never overloads it
    np.testing.assert_array_equal(
        battery.overloaded(np.array([LIMIT_W - 1.0, LIMIT_W, LIMIT_W + 1.0]), VOLTAGE_V, RESISTANCE_OHM),
        [0.0, 0.0, 1.0],
    )
