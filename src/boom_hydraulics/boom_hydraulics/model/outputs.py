"""The outputs of a simulation: every quantity the node publishes and a run records.

A model's ``outputs`` gives them as one tuple of floats in the order of :data:`OUTPUT_NAMES`,
flags as 1.0 or 0.0 (what compiled code keeps in a row of a table); its ``observe`` gives
them by name, flags as booleans (:func:`by_name`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..jit import jitable
from .kinematics import barrel_and_lever
from .ledger import INTEGRALS, TERMS

#: The integrals of the energy ledger's terms beside the battery's and the lift's
#: (model.ledger.INTEGRALS), J since the start: where the battery's energy went.
LEDGER_OUTPUTS: tuple[tuple[str, str, str], ...] = tuple(
    (f"{name}_j", "J", f"since the start: {meaning}") for name, _, _, meaning in TERMS if name in INTEGRALS[2:-1]
)

#: Output names, units and descriptions, in the order of CSV columns.
OUTPUTS: tuple[tuple[str, str, str], ...] = (
    ("t", "s", "simulated time"),
    ("q1", "m", "cylinder length q1"),
    ("v", "m/s", "rod velocity"),
    ("a", "m/s^2", "rod acceleration"),
    ("alpha", "rad", "boom elevation (eq. 4)"),
    ("alpha_rate", "rad/s", "boom angular rate"),
    ("p1", "Pa", "piston-chamber pressure"),
    ("p2", "Pa", "rod-chamber pressure"),
    ("q_in1", "m^3/s", "flow into the piston chamber"),
    ("q_in2", "m^3/s", "flow into the rod chamber"),
    ("f_hyd", "N", "hydraulic rod force p1 S1 - p2 S2"),
    ("f_load", "N", "load force of eq. 10"),
    ("f_friction", "N", "seal friction force, opposing the motion"),
    ("u", "1", "valve command"),
    ("x_v", "1", "spool position applied"),
    ("p_supply", "Pa", "supply pressure: at the valve P port, or the EHA's higher line"),
    ("power", "W", "hydraulic power drawn from the supply at the valve's P port"),
    ("supply_energy", "J", "energy drawn from the supply at the valve's P port"),
    ("valve_loss_energy", "J", "energy dissipated in the valve and relief valves"),
    ("battery_power", "W", "chemical power the battery gives (negative: takes back; NaN in paper mode)"),
    ("battery_drawn", "J", "energy the battery gave since the start"),
    ("battery_returned", "J", "energy the battery took back since the start (a generating motor)"),
    ("lift_work", "J", "potential energy raised since the start: the useful work of the lifts"),
    *LEDGER_OUTPUTS,
    ("void1", "m^3", "void (gas and vapour) volume in the piston chamber while it cavitates"),
    ("void2", "m^3", "void volume in the rod chamber while it cavitates"),
    ("boom_deflection", "m", "elastic boom: the tip's deflection normal to the boom, up positive (0: rigid)"),
    ("boom_deflection_rate", "m/s", "elastic boom: the tip deflection's rate"),
    (
        "hinge_force_x",
        "N",
        "force of the hinge pin on the boom at its pivot O, along the boom to the tip (0 in paper mode)",
    ),
    (
        "hinge_force_z",
        "N",
        "force of the hinge pin on the boom at O, normal to the boom, up at alpha = 0 (0 in paper mode)",
    ),
    ("at_end_stop", "bool", "rod against an end stop"),
    ("cavitation", "bool", "a chamber at the cavitation floor"),
    ("relief_open", "bool", "a relief valve passes flow"),
    ("pump_saturated", "bool", "pump at its maximum flow"),
    (
        "battery_overloaded",
        "bool",
        "the drive asks more power than the battery can give, U^2 / (4 R) (eq. D11): the energy ledger does not close",
    ),
)
OUTPUT_NAMES = tuple(name for name, _, _ in OUTPUTS)
#: The battery's outputs (the physical model's energy ledger): NaN in paper mode, which has none.
BATTERY_OUTPUTS = (
    "battery_power", "battery_drawn", "battery_returned", "lift_work", *(name for name, _, _ in LEDGER_OUTPUTS)
)  # fmt: skip
#: The outputs that must be finite for a state to be published (all but the battery's).
PUBLISHED_FINITE = tuple(name for name in OUTPUT_NAMES if name not in BATTERY_OUTPUTS)


#: What a state publishes (Simulator.published), in this order: every output, then the
#: cylinder barrel's angle (rad) and rate (rad/s) and the lever (rad/m) of model.kinematics, and
#: 1.0 where the outputs a state publishes (PUBLISHED_FINITE) are finite, else 0.0: a NaN is
#: never published.
PUBLISHED_NAMES = (*OUTPUT_NAMES, "barrel", "barrel_rate", "lever", "finite")
# (compiled, published() takes a model's outputs as a tuple of one type, indexed at run time:
# every output is a float64, flags 1.0 or 0.0)
_FINITE_INDICES = tuple(OUTPUT_NAMES.index(name) for name in PUBLISHED_FINITE)
_Q1, _V = OUTPUT_NAMES.index("q1"), OUTPUT_NAMES.index("v")


@jitable
def published(values: Any, a_m: float, b_m: float, h_m: float) -> np.ndarray:
    """The outputs ``values`` of one instant (a tuple in the order of OUTPUT_NAMES) as a
    state publishes them (PUBLISHED_NAMES), for the boom geometry a, b, h (m, eq. 1-5): one
    compiled call a tick for the node's five state messages."""
    n = len(values)
    row = np.empty(n + 4)
    for i in range(n):
        row[i] = values[i]
    finite = 1.0
    for i in _FINITE_INDICES:
        if not math.isfinite(values[i]):
            finite = 0.0
    row[n], row[n + 1], row[n + 2] = barrel_and_lever(values[_Q1], values[_V], a_m, b_m, h_m)
    for i in range(n, n + 3):
        if not math.isfinite(row[i]):
            finite = 0.0
    row[n + 3] = finite
    return row


#: The outputs the run metrics take (solve.streaming), in their order: each model's ``samples``
#: gives these alone, so that a run that keeps no table computes nothing else per sample.
SAMPLE_NAMES = (
    "t", "q1", "v", "alpha", "p1", "p2", "u", "cavitation", "relief_open", "supply_energy", "valve_loss_energy",
    "battery_drawn", "battery_returned", "lift_work",
)  # fmt: skip
#: Outputs that are flags (0.0 or 1.0 in a table of floats).
BOOLEAN_OUTPUTS = tuple(name for name, unit, _ in OUTPUTS if unit == "bool")
#: Where the flags are among the outputs.
_FLAG_INDICES = tuple(i for i, name in enumerate(OUTPUT_NAMES) if name in BOOLEAN_OUTPUTS)


def by_name(values: tuple) -> dict[str, Any]:
    """The outputs ``values`` (in the order of OUTPUT_NAMES) by name, flags as booleans
    (floats or arrays alike)."""
    out = dict(zip(OUTPUT_NAMES, values))
    for i in _FLAG_INDICES:
        out[OUTPUT_NAMES[i]] = values[i] != 0.0
    return out
