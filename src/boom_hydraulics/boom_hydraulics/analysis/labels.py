"""What the plots call things: the drives and the energy ledger's terms in words, and a
parameter or column as an axis label with the unit a reader expects (a piston in mm, a
pressure in MPa), with the scale from its SI value."""

from __future__ import annotations

import math
from typing import NamedTuple

from ..model import drives, parameters

#: The drives (parameters.DRIVES) as a legend names them: each drive module's LABEL.
DRIVE_WORDS: dict[str, str] = {name: module.LABEL for name, module in drives.DRIVES.items()}

#: The energy ledger's terms (model.ledger.TERMS but its sources), the lift's work and the
#: battery's returned energy, as a breakdown's legend names them.
TERM_WORDS: dict[str, str] = {
    "lift_work": "lift work (potential energy raised)",
    "battery_returned": "returned to the battery",
    "battery_loss": "battery resistance",
    "motor_loss": "motor and inverter",
    "standby_loss": "standby (inverter, controller, auxiliaries)",
    "pump_volumetric_loss": "pump leakage",
    "pump_mechanical_loss": "pump friction",
    "main_relief_loss": "main relief valve",
    "valve_loss": "throttling in valves and checks",
    "leakage_loss": "valve leakage",
    "port_relief_loss": "port relief valves",
    "friction_work": "seal friction",
    "end_stop_work": "end stops",
    "ambient_work": "ambient pressure on the rod",
    "external_work": "external rod force",
    "oil_work": "oil compression (net)",
    "rotor_power": "rotor kinetic energy (net)",
    "kinetic_power": "kinetic energy (net)",
    "potential_power": "potential energy (net)",
    "accumulator_loss": "accumulator orifice",
    "gas_power": "accumulator gas (net)",
    "line_loss": "hose friction",
    "structural_loss": "structural damping of the boom",
}

#: Sweep columns that are not parameters, in words.
COLUMN_WORDS: dict[str, str] = {
    "operator": "operator (cycle seed)",
    "config": "config file",
}

#: SI units shown in another unit: (shown, factor from SI).
_SHOWN = {
    "Pa": ("MPa", 1e-6),
    "J": ("kJ", 1e-3),
    "W": ("kW", 1e-3),
    "rad": ("deg", 180.0 / math.pi),
    "m^3": ("cm³", 1e6),
    "m^3/s": ("L/min", 6e4),
}
#: Lengths shown in mm (a cylinder's and an orifice's sizes), beside those in m (the boom's).
_MILLIMETRES = ("diameter", "dead_volume", "presliding")
#: Parts of a parameter's name that spell its unit, dropped from its words.
_UNIT_TOKENS = {"m", "m2", "m3", "kg", "s", "pa", "n", "hz", "kwh", "v", "ohm", "rad", "1"}


class Quantity(NamedTuple):
    """A column as an axis shows it: ``label`` (words and unit) and ``scale`` (shown value per
    stored value)."""

    label: str
    scale: float


def drive_words(name: object) -> str:
    """A drive's name in words (an unknown name as it is)."""
    return DRIVE_WORDS.get(str(name), str(name))


def term_words(name: str) -> str:
    """A ledger term's name in words, without a ``_j`` ending (an unknown name as it is)."""
    bare = name.removesuffix("_j")
    return TERM_WORDS.get(bare, bare.replace("_", " "))


def value_words(column: str, value: object) -> str:
    """A category of ``column`` in words: a drive's name, else the value as it is."""
    return drive_words(value) if column == "drive" else str(value)


def quantity(column: str) -> Quantity:
    """``column`` (a parameter's name or a sweep's column) as an axis label with its unit:
    ``piston_diameter_m`` is "piston diameter [mm]" at 1e3, ``supply_pressure_pa``
    "supply pressure [MPa]" at 1e-6, ``operator`` "operator (cycle seed)"."""
    if column in COLUMN_WORDS:
        return Quantity(COLUMN_WORDS[column], 1.0)
    if column not in parameters.NAMES:
        return Quantity(column.replace("_", " "), 1.0)
    unit = str(parameters.describe(column)["unit"])
    tokens = column.split("_")
    while len(tokens) > 1 and tokens[-1] in _UNIT_TOKENS:
        tokens.pop()
    words = " ".join(tokens)
    shown, scale = _SHOWN.get(unit, (unit, 1.0))
    if unit == "m" and any(part in column for part in _MILLIMETRES):
        shown, scale = "mm", 1e3
    shown = shown.replace("^2", "²").replace("^3", "³")
    return Quantity(f"{words} [{shown}]" if shown else words, scale)


def value_with_unit(column: str, value: object) -> str:
    """One value of ``column`` for a reader: a number in its shown unit to 3 significant digits
    ("43.7 mm"), a category in words."""
    if isinstance(value, str):  # (numpy's str_ too)
        return value_words(column, value)
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return value_words(column, value)
    label, scale = quantity(column)
    unit = label[label.rfind("[") + 1 : -1] if label.endswith("]") else ""
    return f"{number * scale:.3g} {unit}".strip()
