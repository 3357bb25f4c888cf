"""FMI 2.0 units from the model's unit strings: the name a tool shows, and the SI base units.

The model spells its units ``N s/m^2``, ``m^3/(s Pa)``, ``1/rad`` (parameters.py,
outputs.py). An FMU names each unit a variable uses in its UnitDefinitions, with the
exponents of the SI base units, so that a tool (OpenModelica, Simulink) can check and
convert them. The names here follow Modelica's unit syntax (``N.s/m2``, ``m3/(s.Pa)``),
which those tools read.
"""

from __future__ import annotations

import math

#: The base units of FMI 2.0's BaseUnit element, in its order.
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

#: Each symbol the model's units use, as exponents of the base units.
SYMBOLS: dict[str, dict[str, int]] = {
    "1": {},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "rad": {"rad": 1},
    "Hz": {"s": -1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "Pa": {"kg": 1, "m": -1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
    "A": {"A": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "kWh": {"kg": 1, "m": 2, "s": -2},
}
#: Symbols that are a multiple of their base units: the factor (FMI's BaseUnit ``factor``).
FACTORS: dict[str, float] = {"kWh": 3.6e6}


def base_exponents(unit: str) -> dict[str, int]:
    """The base-unit exponents of a model unit: ``'N s/m^2'`` -> ``{'kg': 1, 'm': -1, 's': -1}``
    (``''`` and ``'1'``: dimensionless, ``{}``). ValueError for a symbol not in :data:`SYMBOLS`."""
    numerator, _, denominator = unit.partition("/")
    total: dict[str, int] = {}
    for part, sign in ((numerator, 1), (denominator.strip().removeprefix("(").removesuffix(")"), -1)):
        for factor in part.split():
            symbol, _, power = factor.partition("^")
            if symbol not in SYMBOLS:
                raise ValueError(f"unit {unit!r}: unknown symbol {symbol!r}; add it to fmu.units.SYMBOLS")
            for base, exponent in SYMBOLS[symbol].items():
                total[base] = total.get(base, 0) + sign * exponent * int(power or 1)
    return {base: total[base] for base in BASE_UNITS if total.get(base)}


def unit_name(unit: str) -> str:
    """A model unit in Modelica's syntax: ``'N s/m^2'`` -> ``'N.s/m2'``; dimensionless ``''`` -> ``'1'``."""
    return unit.strip().replace("^", "").replace(" ", ".") or "1"


def base_factor(unit: str) -> float:
    """How many of its base units one ``unit`` is: ``'kWh'`` -> 3.6e6 (1 for most)."""
    numerator, _, denominator = unit.partition("/")
    factor = 1.0
    for part, sign in ((numerator, 1), (denominator.strip().removeprefix("(").removesuffix(")"), -1)):
        for item in part.split():
            symbol, _, power = item.partition("^")
            factor *= FACTORS.get(symbol, 1.0) ** (sign * int(power or 1))
    return factor


#: The units a fluid-power engineer reads beside the SI ones, by the SI unit's name (as
#: :func:`unit_name` writes it): (name, factor) with display value = factor x SI value, the
#: first the one a tool shows by default (the variables' ``displayUnit``).
DISPLAY_UNITS: dict[str, tuple[tuple[str, float], ...]] = {
    "Pa": (("bar", 1.0e-5), ("MPa", 1.0e-6)),
    "m3/s": (("L/min", 6.0e4),),
    "m": (("mm", 1.0e3),),
    "m/s": (("mm/s", 1.0e3),),
    "rad": (("deg", 180.0 / math.pi),),
    "rad/s": (("deg/s", 180.0 / math.pi), ("rpm", 30.0 / math.pi)),
    "m3": (("L", 1.0e3), ("cm3", 1.0e6)),
    "N": (("kN", 1.0e-3),),
    "W": (("kW", 1.0e-3),),
    "J": (("kJ", 1.0e-3),),
    "m3/(s.Pa)": (("L/(min.bar)", 6.0e9),),
}


def display_units(unit: str) -> tuple[tuple[str, float], ...]:
    """The display units of a model unit (``'Pa'`` -> bar and MPa); none for most."""
    return DISPLAY_UNITS.get(unit_name(unit), ())
