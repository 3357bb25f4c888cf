"""The FMU's units (fmu/units.py), each checked against its definition: the SI base-unit
exponents a tool (OpenModelica, Simulink) converts with, and the display units a fluid-power
engineer reads (bar, L/min, rpm), each factor derived here from the unit's own definition."""

from __future__ import annotations

import math

import pytest

from boom_hydraulics.fmu.units import (
    BASE_UNITS,
    DISPLAY_UNITS,
    SYMBOLS,
    base_exponents,
    base_factor,
    display_units,
    unit_name,
)


def _times(*units: dict[str, int], power: int = 1) -> dict[str, int]:
    """The product of units as base exponents (an independent sum, not the module's parser)."""
    total: dict[str, int] = {}
    for unit in units:
        for base, n in unit.items():
            total[base] = total.get(base, 0) + n
    return {b: n * power for b, n in total.items() if n}


KG, M, S, A, RAD = {"kg": 1}, {"m": 1}, {"s": 1}, {"A": 1}, {"rad": 1}
PER_S, PER_M, PER_A = {"s": -1}, {"m": -1}, {"A": -1}
NEWTON = _times(KG, M, PER_S, PER_S)  # F = m a
JOULE = _times(NEWTON, M)  # W = F s
WATT = _times(JOULE, PER_S)  # P = W / t
VOLT = _times(WATT, PER_A)  # U = P / I
DEFINITIONS = {
    "1": {},
    "kg": KG,
    "m": M,
    "s": S,
    "rad": RAD,
    "A": A,
    "Hz": PER_S,
    "N": NEWTON,
    "Pa": _times(NEWTON, PER_M, PER_M),  # p = F / A
    "J": JOULE,
    "W": WATT,
    "V": VOLT,
    "ohm": _times(VOLT, PER_A),  # R = U / I
    "kWh": _times(WATT, S),  # an energy: 1000 W for 3600 s
}


def test_each_symbol_is_its_definition_in_base_units():
    assert set(SYMBOLS) == set(DEFINITIONS)
    for symbol, definition in DEFINITIONS.items():
        assert base_exponents(symbol) == definition, symbol
        assert set(definition) <= set(BASE_UNITS)


def test_kwh_is_3_6_megajoules_and_its_powers_scale_alike():
    assert base_factor("kWh") == pytest.approx(1000.0 * 3600.0, rel=1e-15)
    assert base_factor("J") == 1.0 and base_factor("W s") == 1.0 and base_factor("") == 1.0
    assert base_factor("1/kWh") == pytest.approx(1.0 / 3.6e6, rel=1e-15)  # a price per kWh
    assert base_factor("kWh^2") == pytest.approx(3.6e6**2, rel=1e-15)
    assert base_factor("kWh/(kWh s)") == pytest.approx(1.0, rel=1e-15)
    assert base_factor("N m/kWh") == pytest.approx(1.0 / 3.6e6, rel=1e-15)


@pytest.mark.parametrize(
    ("unit", "expected"),
    [
        ("N s/m^2", {"kg": 1, "m": -1, "s": -1}),  # a viscous damping per area
        ("N s/m", {"kg": 1, "s": -1}),
        ("N m s/rad", {"kg": 1, "m": 2, "s": -1, "rad": -1}),
        ("m^3/(s Pa)", {"kg": -1, "m": 4, "s": 1}),  # a valve's flow gain
        ("kg/m^3", {"kg": 1, "m": -3}),
        ("kg m^2", {"kg": 1, "m": 2}),
        ("m/s^2", {"m": 1, "s": -2}),
        ("1/rad", {"rad": -1}),
        ("N m/A", {"kg": 1, "m": 2, "s": -2, "A": -1}),  # a motor's torque constant = V s/rad
        ("N m", JOULE),
        ("W s", JOULE),
        ("Pa m^3", JOULE),  # a pressure times a volume is an energy
        ("m^3/s", {"m": 3, "s": -1}),
        ("", {}),
        ("1", {}),
    ],
)
def test_model_units_in_base_exponents(unit, expected):
    assert base_exponents(unit) == expected


def test_base_exponents_are_in_fmi_order_and_drop_zeros():
    assert list(base_exponents("rad m kg s A")) == ["kg", "m", "s", "A", "rad"]
    assert base_exponents("m/m") == {} and base_exponents("N/N") == {}


def test_an_unknown_symbol_is_one_clear_error():
    with pytest.raises(ValueError, match="'bar'"):
        base_exponents("bar")
    with pytest.raises(ValueError, match="'psi'"):
        base_exponents("m/psi")


def test_unit_names_in_modelica_syntax():
    assert unit_name("N s/m^2") == "N.s/m2"
    assert unit_name("m^3/(s Pa)") == "m3/(s.Pa)"
    assert unit_name(" Pa ") == "Pa"
    assert unit_name("") == "1" and unit_name("  ") == "1"


# Each display unit from its definition: bar = 1e5 Pa, L = 1e-3 m^3, min = 60 s, deg = pi/180 rad,
# rev = 2 pi rad, cm = 1e-2 m.
BAR, LITRE, MINUTE, DEGREE, REV = 1.0e5, 1.0e-3, 60.0, math.pi / 180.0, 2.0 * math.pi
DISPLAYED = {
    "Pa": {"bar": 1.0 / BAR, "MPa": 1.0 / 1.0e6},
    "m^3/s": {"L/min": MINUTE / LITRE},
    "m": {"mm": 1.0 / 1.0e-3},
    "m/s": {"mm/s": 1.0 / 1.0e-3},
    "rad": {"deg": 1.0 / DEGREE},
    "rad/s": {"deg/s": 1.0 / DEGREE, "rpm": MINUTE / REV},
    "m^3": {"L": 1.0 / LITRE, "cm3": 1.0 / 1.0e-2**3},
    "N": {"kN": 1.0 / 1.0e3},
    "W": {"kW": 1.0 / 1.0e3},
    "J": {"kJ": 1.0 / 1.0e3},
    "m^3/(s Pa)": {"L/(min.bar)": (MINUTE / LITRE) * BAR},
}


@pytest.mark.parametrize("unit", sorted(DISPLAYED))
def test_each_display_factor_is_its_definition(unit):
    shown = display_units(unit)
    assert {name for name, _ in shown} == set(DISPLAYED[unit])
    for name, factor in shown:
        assert factor == pytest.approx(DISPLAYED[unit][name], rel=1e-12), (unit, name)


def test_the_default_display_unit_is_the_engineers_first_choice():
    # The first is the variables' displayUnit: pressures in bar, speeds in deg/s, volumes in L.
    first = {unit: display_units(unit)[0][0] for unit in ("Pa", "rad/s", "m^3", "m^3/s")}
    assert first == {"Pa": "bar", "rad/s": "deg/s", "m^3": "L", "m^3/s": "L/min"}


def test_units_without_a_display_unit_show_none():
    assert display_units("kg") == () and display_units("N s/m") == () and display_units("") == ()
    assert set(DISPLAY_UNITS) == {unit_name(u) for u in DISPLAYED}


def test_display_factors_are_consistent_with_each_other():
    # 1 bar of 1 L/(min bar) valve gain is 1 L/min: the gain's factor is the flow's over the pressure's.
    flow = dict(display_units("m^3/s"))["L/min"]
    pressure = dict(display_units("Pa"))["bar"]
    gain = dict(display_units("m^3/(s Pa)"))["L/(min.bar)"]
    assert gain == pytest.approx(flow / pressure, rel=1e-12)
    # 1 rpm is 6 deg/s.
    speeds = dict(display_units("rad/s"))
    assert speeds["deg/s"] / speeds["rpm"] == pytest.approx(6.0, rel=1e-12)
