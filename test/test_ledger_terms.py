"""Each term of the energy ledger against its own definition (docs/model.md, "Energy ledger").

The ledger's closure (test_ledger.py) cannot tell a term booked under the wrong name or with
a wrong share from the right one where the error cancels in the sum (the chamber that shrinks
in the stops, the standby's parts, the battery's split into drawn and returned): these tests
check each term at a known operating point, as the rate of the energy it names, and the
integrals and the imbalance of a run at their definitions' edges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIG

from boom_hydraulics.model import config, drives, ledger, physical
from boom_hydraulics.model.drives import DRIVES
from boom_hydraulics.model.electric_motor import MotorLosses, machine_loss_w
from boom_hydraulics.model.geometry import boom_angle_rad, lever_rad_per_m
from boom_hydraulics.model.parameters import Parameters, with_updates

P = Parameters()
#: The 1 t loader crane: accumulator, hoses, elastic boom, inverter standby (20 W) and
#: auxiliaries (40 W) all on, so that every term of the ledger is at work.
CRANE = config.load(CONFIG / "loader_crane_1t.yaml")


def test_the_cylinder_side_books_each_term_as_its_definition_at_one_operating_point():
    """eq. D28 at a made-up point where every input differs (pressures above tank, the rod
    extending): each term is its definition, and the chamber that the stops shrink is booked
    to the stops only where the chambers' dV/dq1 differ from the rod's areas."""
    v, acc = 0.07, -0.3
    p1, p2, p_t, p_amb = 9.0e6, 2.5e6, 2.0e5, 1.0e5
    q_in1, q_in2, qr1, qr2 = 4.0e-4, -3.0e-4, 2.0e-5, 3.0e-5
    s1, s2 = 5.0e-3, 2.0e-3
    f_fr, f_stop, f_spring, f_ext = 700.0, 0.0, 250.0, -1200.0
    k, dk, cos_a, inertia, weight = 1.3, -0.4, 0.8, 450.0, 6000.0
    args = (v, acc, p1, p2, q_in1, q_in2, s1, -s2, qr1, qr2, f_fr, f_stop, f_spring, k, dk, cos_a, inertia, weight)
    cyl = ledger.cylinder_side(*args, s1, s2, p_t, p_amb, f_ext)
    g1, g2 = p1 - p_t, p2 - p_t
    assert cyl.port_relief_loss == pytest.approx(g1 * qr1 + g2 * qr2, rel=1e-12)
    assert cyl.oil_work == pytest.approx(g1 * (q_in1 - s1 * v) + g2 * (q_in2 + s2 * v), rel=1e-12)  # (p-p_t)(Q - dV/dt)
    assert cyl.friction_work == pytest.approx(f_fr * v, rel=1e-12)
    assert cyl.end_stop_work == pytest.approx(0.0, abs=1e-9)  # outside the stops: dV/dq1 are the rod's areas
    assert cyl.ambient_work == pytest.approx((p_amb - p_t) * (s1 - s2) * v, rel=1e-12)
    assert cyl.external_work == pytest.approx(-f_ext * v, rel=1e-12) and cyl.external_work > 0.0
    assert cyl.kinetic_power == pytest.approx(inertia * k * v * (k * acc + dk * v * v), rel=1e-12)
    assert cyl.potential_power == pytest.approx(weight * cos_a * k * v + f_spring * v, rel=1e-12)
    # pressed into the stops: the stops' force does work, and the chambers shrink by less than
    # the rod's areas sweep (dV/dq1 = 0.9 s1, -0.8 s2): the difference is the stops' too
    pressed = (v, acc, p1, p2, q_in1, q_in2, 0.9 * s1, -0.8 * s2, qr1, qr2, f_fr, 3.0e4, *args[12:])
    cyl = ledger.cylinder_side(*pressed, s1, s2, p_t, p_amb, f_ext)
    shrunk = (g1 * 0.9 * s1 - g2 * 0.8 * s2) * v - (g1 * s1 - g2 * s2) * v
    assert cyl.end_stop_work == pytest.approx(shrunk - 3.0e4 * v, rel=1e-12)
    assert cyl.oil_work == pytest.approx(g1 * (q_in1 - 0.9 * s1 * v) + g2 * (q_in2 + 0.8 * s2 * v), rel=1e-12)


def _boom_energy(q1: float, v: float, c: physical.Constants) -> tuple[float, float]:
    """(kinetic, potential) energy of the rigid boom, payload and spring, J (eq. 8, 9)."""
    k = lever_rad_per_m(q1, c.a, c.b)
    spring = 0.5 * c.spring * (q1 - c.spring_free) ** 2
    return 0.5 * c.inertia * k * k * v * v, c.weight_coeff * math.sin(boom_angle_rad(q1, c.a, c.b, c.h)) + spring


@pytest.mark.parametrize(("q1", "v", "u"), [(1.2, 0.08, 0.6), (1.5, -0.12, -0.8), (1.35, 0.03, 0.0)])
def test_the_kinetic_and_potential_power_are_the_rates_of_the_booms_energies(q1, v, u):
    """kinetic_power and potential_power are d/dt of the boom's kinetic and potential energy
    (weight and spring) along the model's own motion (central difference of q1' = v, v' = a)."""
    p = with_updates(P, spring_stiffness_n_m=2000.0)
    c = physical.constants(p)
    y = physical.initial_state(p, q1)
    y[1] = v
    acc = physical._terms(y, c, u, math).acc
    terms = physical.ledger(0.0, y, c, u)
    h = 1e-6
    ahead, behind = _boom_energy(q1 + h * v, v + h * acc, c), _boom_energy(q1 - h * v, v - h * acc, c)
    assert terms.kinetic_power == pytest.approx((ahead[0] - behind[0]) / (2 * h), rel=1e-6, abs=1e-6)
    assert terms.potential_power == pytest.approx((ahead[1] - behind[1]) / (2 * h), rel=1e-6)
    assert terms.end_stop_work == pytest.approx(0.0, abs=1e-9)  # mid-stroke: the stops take nothing


def test_the_electric_chain_draws_the_standby_and_auxiliaries_and_the_battery_splits_its_power():
    """eq. D5, D8, D9: the inverter draws T w + P_m + P_sb, P_sb the drive's standby with the
    inverter's P_0 and the auxiliaries' P_aux; the battery gives U I with I from U I - R I^2 = P."""
    c = physical.constants(CRANE)
    assert (c.inverter_standby, c.auxiliary_power) == (20.0, 40.0)
    supply = drives.supply((1.0e7, 0.0, 0.0), 0.5, 0.5, 1.3, 0.05, 8.0e6, 1.0e6, c)
    supply = supply._replace(torque=30.0, speed=150.0, standby_loss=7.0)
    chain = ledger.electric_chain(supply, c)
    m = MotorLosses(c.motor_copper, c.motor_iron, c.motor_current, c.motor_eddy, c.motor_windage, c.inverter_standby)
    assert chain.shaft_power == pytest.approx(30.0 * 150.0, rel=1e-12)
    assert chain.motor_loss == pytest.approx(machine_loss_w(30.0, 150.0, m), rel=1e-12) and chain.motor_loss > 0.0
    assert chain.standby_loss == pytest.approx(7.0 + 20.0 + 40.0, rel=1e-12)
    electrical = 30.0 * 150.0 + chain.motor_loss + 67.0
    assert chain.electrical_power == pytest.approx(electrical, rel=1e-12)
    u, r = c.battery_voltage, c.battery_resistance
    assert chain.battery_power == pytest.approx(u * chain.current, rel=1e-12)
    assert chain.battery_power - chain.battery_loss == pytest.approx(electrical, rel=1e-12)
    assert chain.battery_loss == pytest.approx(r * chain.current**2, rel=1e-12) and chain.current > 0.0
    terms = ledger.assemble(chain, supply, ledger.Cylinder(*[0.0] * 8), 0.0, 0.0, 0.0, 0.0, 0.0)
    assert terms.standby_loss == chain.standby_loss and terms.motor_loss == chain.motor_loss


def _random_crane_state(rng: np.random.Generator, name: str) -> tuple[list[float], float]:
    """A state of the 1 t crane anywhere it goes: the rod moving either way in its stroke or
    its stops, chambers and lines from cavitating to high pressure, every line's flow, the
    accumulator filled, the boom's mode ringing, the drive's states anywhere they go."""
    p = CRANE
    y = physical.initial_state(with_updates(p, drive=name))
    y[0] = rng.uniform(p.cylinder_min_length_m - 2e-3, p.cylinder_max_length_m + 2e-3)
    y[1] = rng.uniform(-0.2, 0.2)
    y[2], y[3] = rng.uniform(-2e5, 2.2e7, size=2)
    y[4] = rng.uniform(-1, 1)
    for i, unit in zip(physical.HOSE_STATES, physical.hoses.STATE_UNITS):
        y[i] = rng.uniform(-2e5, 2e7) if unit == "Pa" else rng.uniform(-3e-4, 3e-4)
    y[physical.ACCUMULATOR_STATE] = rng.uniform(5.0e-5, 3.0e-4)  # of its 0.5 L of gas
    y[physical.BOOM_STATE], y[physical.BOOM_STATE + 1] = rng.uniform(-0.02, 0.02), rng.uniform(-0.3, 0.3)
    slowest = 0.0 if DRIVES[name].VALVE else -200.0  # a valve drive's motor turns one way (motor_speed)
    for k, kind in enumerate(DRIVES[name].STATE_SCALES):
        y[physical.DRIVE_STATE + k] = {
            "pressure": rng.uniform(-2e5, 2e7),
            "angular_velocity": rng.uniform(slowest, 200.0),
            "unit": rng.uniform(-1, 1),
        }[kind]
    return y, rng.uniform(-1, 1)


@pytest.mark.parametrize("name", DRIVES)
def test_with_every_element_on_the_ledger_closes_and_each_of_their_terms_is_at_work(name):
    """The 1 t crane (accumulator, hoses, elastic boom, standby all on): the ledger closes at
    random states, and the accumulator's, hoses' (but for the actuator, which has no oil),
    boom's and standby terms are not zero, so
    that a term dropped from the sum or booked with the wrong sign would show."""
    rng = np.random.default_rng(hash(name) % 2**32)
    c = physical.constants(with_updates(CRANE, drive=name))
    oil = ("accumulator_loss", "gas_power", "line_loss") if DRIVES[name].VALVE or name == "pump_controlled" else ()
    seen = dict.fromkeys((*oil, "structural_loss", "standby_loss"), 0)  # the actuator has no oil
    for _ in range(40):
        y, u = _random_crane_state(rng, name)
        terms = physical.ledger(0.0, y, c, u)
        scale = sum(abs(value) for value in terms)
        # it closes wherever the battery can give what the drive asks; a random state may ask more
        # (a pump stroked far past its displacement by a reverse flow at a motor near standstill,
        # which no run reaches), and the output says so (eq. D11)
        closes = abs(ledger.residual_w(terms)) <= 1e-9 * scale
        assert closes != physical.observe(0.0, y, c, u)["battery_overloaded"], (name, y, u, terms)
        if not closes:
            continue
        for term in seen:
            seen[term] += abs(getattr(terms, term)) > 1e-6 * scale
        assert terms.standby_loss >= 60.0  # the inverter's 20 W and the auxiliaries' 40 W at least
    assert min(seen.values()) >= 10, seen


@pytest.mark.parametrize("resistance_ohm", [0.5, 10.0])
def test_a_battery_asked_for_more_than_it_can_give_is_flagged_and_only_then_the_ledger_stays_open(resistance_ohm):
    """Eq. D11 with the 1 t crane's pump on full flow into a loaded piston side (its motor asks
    about 10 kW): its 450 V battery gives at most U^2 / (4 R) = 101 kW through 0.5 ohm and 5 kW
    through 10 ohm. The flag is set where the ask is past that, and only there the terminals
    give less than asked, by the ledger's residual."""
    p = with_updates(CRANE, drive="pressure_compensated", battery_resistance_ohm=resistance_ohm)
    c = physical.constants(p)
    y = physical.initial_state(p)
    y[2], y[4] = 15e6, 1.0  # the piston side holding the load, the spool open
    y[physical.DRIVE_STATE + 1] = p.pump_speed_rad_s  # the motor at full speed (speed on demand)
    out = physical.observe(0.0, y, c, 1.0)
    terms = physical.ledger(0.0, y, c, 1.0)
    terminals = terms.battery_power - terms.battery_loss  # U I - R I^2 (eq. D8)
    asked = terminals - ledger.residual_w(terms)  # what the motor, inverter and auxiliaries take (eq. D5)
    limit = p.battery_voltage_v**2 / (4.0 * p.battery_resistance_ohm)  # eq. D11
    assert 8e3 < asked < 20e3
    assert out["battery_overloaded"] == (asked > limit) == (resistance_ohm == 10.0)
    if out["battery_overloaded"]:
        assert terminals < limit < asked  # the terminals give less than asked: the ledger stays open
    else:
        assert abs(ledger.residual_w(terms)) <= 1e-9 * asked


def test_the_integrals_rates_split_the_battery_into_drawn_and_returned_and_lift_work_takes_the_raising():
    """integral_rates in the order of INTEGRALS: each term's rate under its name, the battery's
    power as drawn (> 0) or returned (< 0), both >= 0, and lift_work the potential power's
    positive part."""
    values = [float(k + 1) for k in range(len(ledger.TERM_NAMES))]
    for battery, potential in ((250.0, 40.0), (-250.0, -40.0)):
        terms = ledger.Ledger(*values)._replace(battery_power=battery, potential_power=potential)
        rates = dict(zip(ledger.INTEGRALS, ledger.integral_rates(terms), strict=True))
        assert rates["battery_drawn"] == max(battery, 0.0) and rates["battery_returned"] == max(-battery, 0.0)
        assert rates["lift_work"] == max(potential, 0.0)
        for name in ledger.TERM_NAMES[1:]:
            assert rates[name] == getattr(terms, name), name


def test_the_imbalance_counts_the_reservoir_as_a_source_and_its_ratio_is_over_what_was_drawn():
    """energies_of: the EHA's reservoir gives (or takes) energy beside the battery, the ratio is
    over what both gave (the reservoir's magnitude), an imbalance either way is a ratio > 0,
    and a run that drew nothing has a ratio of 0, not a division by zero."""
    zero = {name: 0.0 for name in ledger.INTEGRALS}
    run = zero | {"battery_drawn": 1000.0, "battery_returned": 200.0, "reservoir_power": -50.0}
    run |= {"motor_loss": 300.0, "valve_loss": 460.0}  # 10 J short of the 750 J the sources gave
    energies = ledger.energies_of(run)
    assert energies["imbalance"] == pytest.approx(-10.0, abs=1e-12)
    assert energies["imbalance_ratio"] == pytest.approx(10.0 / 1050.0, rel=1e-12)
    assert ledger.energies_of(run | {"reservoir_power": 50.0})["imbalance"] == pytest.approx(90.0, abs=1e-12)
    idle = ledger.energies_of(zero | {"battery_returned": 5.0, "friction_work": -5.0})
    assert idle["imbalance"] == pytest.approx(0.0, abs=1e-12) and idle["imbalance_ratio"] == 0.0
    lost = ledger.energies_of(zero | {"valve_loss": 3.0})  # nothing drawn: no ratio to give
    assert lost["imbalance"] == -3.0 and lost["imbalance_ratio"] == 0.0
    little = ledger.energies_of(zero | {"battery_drawn": 0.5, "valve_loss": 0.4})  # under a joule drawn
    assert little["imbalance_ratio"] == pytest.approx(0.2, rel=1e-12)
