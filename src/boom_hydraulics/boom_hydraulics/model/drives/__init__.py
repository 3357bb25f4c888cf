"""The drives that feed the cylinder, one module each, behind one parameter (``drive``).

A drive is everything between the battery and the cylinder's two lines: motor, pump and,
for the valve drives, the 4/3 valve (model/valve.py). Each drive module offers:

- ``LABEL``: what a plot's legend calls it;
- ``STATE_NAMES`` (at most :data:`STATE_COUNT` states of its own), ``STATE_SCALES`` (the
  model's error control) and ``STATE_UNITS``;
- ``initial_state(d)``: its states at the start, a tuple of :data:`STATE_COUNT`;
- ``supply(z, u, opening, q1, v, p1, p2, d, xp)``: the drive at one instant (:class:`Supply`):
  its states' rates, the flows into the lines, the motor's operating point, its ledger terms;
- ``energy(z, d, xp)`` and ``energy_rate(z, s, d)``: what it stores beside the chambers;
- ``stiffness(z, u, opening, stiff1, stiff2, dt, d, xp)``: how stiffly it holds the lines, and
  its own fastest rate (stepping's stability bound);
- ``VALVE``: whether it feeds the chambers through the 4/3 valve; ``STEADY_SUPPLY``: whether its
  states stand still whatever the load (a linear model leaves them out);
- ``CYLINDER_OIL`` (optional, True if absent): whether its cylinder holds oil; a drive without
  (electro_mechanical) keeps the chambers at tank pressure, where :func:`holds_oil` starts them.
- ``SUPPLY_NODE`` (optional, False if absent): whether it has a supply line, an oil volume with
  a pressure state of its own between pump and valve (fixed_pump), that an accumulator can sit on
  (parameters.SUPPLY_LINE_DRIVES names them). Such a drive's ``supply`` takes one more, last
  argument ``q_draw``: a flow drawn from that node by an element beside the valve (the
  accumulator, m^3/s; its line's state rate and ``line_oil_work`` count it out, and its power
  (p_s - p_t) q_draw is the drawing element's ledger terms), and it offers
  ``node_pressure(z, d)``: the node's pressure, Pa (:func:`node_pressure`). The other drives
  see no draw (:func:`supply` passes none).

:data:`DRIVES` registers them; the functions below call the set's drive (compiled code picks
no function from a dict of modules, so each names the registered drives once, in order).
The model (physical.py), the solver and the analysis name no drive.

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from ...jit import jitable
from ..parameters import DRIVES as DRIVE_CHOICES
from ..parameters import SUPPLY_LINE_DRIVES
from . import electro_mechanical, fixed_pump, load_sensing, pressure_compensated, pump_controlled
from .constants import DriveConstants, Supply, chosen, constants, drive_index, in_use

Num = Any  # float or numpy.ndarray

#: Every drive, by the name the ``drive`` parameter gives it (the one registry of them).
DRIVES: dict[str, ModuleType] = {
    "pressure_compensated": pressure_compensated,
    "fixed_pump": fixed_pump,
    "load_sensing": load_sensing,
    "pump_controlled": pump_controlled,
    "electro_mechanical": electro_mechanical,
}
assert tuple(DRIVES) == DRIVE_CHOICES, "parameters.DRIVES must name the registered drives"
#: How many states the model keeps for the drive (the most any drive has).
STATE_COUNT = 3
assert all(len(m.STATE_NAMES) <= STATE_COUNT for m in DRIVES.values()), "a drive has more states than the model keeps"
assert all(len(m.STATE_NAMES) == len(m.STATE_SCALES) == len(m.STATE_UNITS) for m in DRIVES.values())


@jitable
def uses(d: DriveConstants, index: int) -> Num:
    """1.0 where the set's drive is the registered drive ``index``, else 0.0."""
    return 1.0 * (d.drive == float(index))


@jitable
def initial_state(drive: str, d: DriveConstants) -> tuple[float, float, float]:
    """``DRIVES[drive].initial_state(d)``, as compiled code can call it too."""
    if drive == "pressure_compensated":
        return pressure_compensated.initial_state(d)
    if drive == "fixed_pump":
        return fixed_pump.initial_state(d)
    if drive == "load_sensing":
        return load_sensing.initial_state(d)
    if drive == "pump_controlled":
        return pump_controlled.initial_state(d)
    if drive == "electro_mechanical":
        return electro_mechanical.initial_state(d)
    raise ValueError("no drive of that name")  # parameters.DRIVES names the registered ones


#: Whether each registered drive's cylinder holds oil, in the registry's order (a drive without
#: oil sets ``CYLINDER_OIL = False``: its chambers are a housing at tank pressure).
_OIL = tuple(bool(getattr(module, "CYLINDER_OIL", True)) for module in DRIVES.values())


@jitable
def holds_oil(drive: str) -> bool:
    """Whether the cylinder of drive ``drive`` holds oil (physical.initial_state: else its chambers
    start at tank pressure), as compiled code can ask too."""
    return _OIL[int(drive_index(drive))]


@jitable
def _nothing(zero: Num) -> Supply:
    """A Supply of zeros (what :func:`supply` blends each set's drive into)."""
    return Supply(*(zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero),
                  *(zero, zero, zero, zero, zero, zero, zero))  # fmt: skip


@jitable(inline="always")
def supply(
    z: tuple,
    u: Num,
    opening: Num,
    q1: Num,
    v: Num,
    p1_pa: Num,
    p2_pa: Num,
    d: DriveConstants,
    xp: ModuleType = math,
    q_draw: Num = 0.0,
) -> Supply:
    """The set's drive at one instant (each drive's ``supply``; a batch: each set's); ``q_draw``
    the flow an element beside the valve draws from the supply node of a drive that has one
    (``SUPPLY_NODE``), m^3/s: 0 for the others."""
    s = _nothing(0.0 * p1_pa)
    w = uses(d, 0)
    if in_use(w):
        s = chosen(s, pressure_compensated.supply(z, u, opening, q1, v, p1_pa, p2_pa, d, xp), w)
    w = uses(d, 1)
    if in_use(w):
        s = chosen(s, fixed_pump.supply(z, u, opening, q1, v, p1_pa, p2_pa, d, xp, q_draw), w)
    w = uses(d, 2)
    if in_use(w):
        s = chosen(s, load_sensing.supply(z, u, opening, q1, v, p1_pa, p2_pa, d, xp), w)
    w = uses(d, 3)
    if in_use(w):
        s = chosen(s, pump_controlled.supply(z, u, opening, q1, v, p1_pa, p2_pa, d, xp), w)
    w = uses(d, 4)
    if in_use(w):
        s = chosen(s, electro_mechanical.supply(z, u, opening, q1, v, p1_pa, p2_pa, d, xp), w)
    return s


#: Whether each registered drive has a supply node (``SUPPLY_NODE``), in the registry's order.
_NODE = tuple(bool(getattr(module, "SUPPLY_NODE", False)) for module in DRIVES.values())
assert tuple(n for n, node in zip(DRIVES, _NODE) if node) == SUPPLY_LINE_DRIVES, "parameters.SUPPLY_LINE_DRIVES"


@jitable
def node_pressure(z: tuple, d: DriveConstants) -> Num:
    """The pressure of the set's drive's supply node (``node_pressure`` of a drive with
    ``SUPPLY_NODE``), Pa; tank pressure for a drive without one."""
    w = uses(d, 1)
    return d.p_tank + w * (fixed_pump.node_pressure(z, d) - d.p_tank)


@jitable(inline="always")
def stored(z: tuple, s: Supply, d: DriveConstants, xp: ModuleType = math) -> tuple[Num, Num]:
    """(E, dE/dt): what the set's drive stores beside the chambers, J (each drive's ``energy``),
    and its rate along the drive's rates ``s``, W (each drive's ``energy_rate``)."""
    e, rate = 0.0 * z[0], 0.0 * z[0]
    w = uses(d, 0)
    if in_use(w):
        e, rate = e + w * pressure_compensated.energy(z, d, xp), rate + w * pressure_compensated.energy_rate(z, s, d)
    w = uses(d, 1)
    if in_use(w):
        e, rate = e + w * fixed_pump.energy(z, d, xp), rate + w * fixed_pump.energy_rate(z, s, d)
    w = uses(d, 2)
    if in_use(w):
        e, rate = e + w * load_sensing.energy(z, d, xp), rate + w * load_sensing.energy_rate(z, s, d)
    w = uses(d, 3)
    if in_use(w):
        e, rate = e + w * pump_controlled.energy(z, d, xp), rate + w * pump_controlled.energy_rate(z, s, d)
    w = uses(d, 4)
    if in_use(w):
        e, rate = e + w * electro_mechanical.energy(z, d, xp), rate + w * electro_mechanical.energy_rate(z, s, d)
    return e, rate


@jitable
def energy(z: tuple, d: DriveConstants, xp: ModuleType = math) -> Num:
    """What the set's drive stores beside the chambers, J (:func:`stored`)."""
    return stored(z, _nothing(0.0 * z[0]), d, xp)[0]


@jitable
def energy_rate(z: tuple, s: Supply, d: DriveConstants) -> Num:
    """d/dt of :func:`energy` along the drive's rates ``s``, W (:func:`stored`)."""
    return stored(z, s, d)[1]


@jitable
def _plus(a: tuple, w: Num, b: tuple) -> tuple:
    """a + w b, element by element, of two triples."""
    return a[0] + w * b[0], a[1] + w * b[1], a[2] + w * b[2]


@jitable
def stiffness(
    z: tuple,
    u: Num,
    opening: Num,
    stiff1: Num,
    stiff2: Num,
    dt: float,
    d: DriveConstants,
    xp: ModuleType = math,
    rod_mass_kg: Num = 1e300,
) -> tuple[Num, Num, Num]:
    """(dQ/dp the drive gives line A, line B; its own fastest rate): each drive's ``stiffness``.
    ``rod_mass_kg``: the boom's inertia at the rod where it is light (the elastic boom's root,
    docs/model.md "Elastic boom"; 1e300, none, by default), which a drive that holds the rod
    with a spring of its own (electro_mechanical's screw) counts against it."""
    zero = 0.0 * stiff1
    g = (zero, zero, zero)
    w = uses(d, 0)
    if in_use(w):
        g = _plus(g, w, pressure_compensated.stiffness(z, u, opening, stiff1, stiff2, dt, d, xp))
    w = uses(d, 1)
    if in_use(w):
        g = _plus(g, w, fixed_pump.stiffness(z, u, opening, stiff1, stiff2, dt, d, xp))
    w = uses(d, 2)
    if in_use(w):
        g = _plus(g, w, load_sensing.stiffness(z, u, opening, stiff1, stiff2, dt, d, xp))
    w = uses(d, 3)
    if in_use(w):
        g = _plus(g, w, pump_controlled.stiffness(z, u, opening, stiff1, stiff2, dt, d, xp))
    w = uses(d, 4)
    if in_use(w):
        g = _plus(g, w, electro_mechanical.stiffness(z, u, opening, stiff1, stiff2, dt, d, xp, rod_mass_kg))
    return g


__all__ = (
    "DRIVES",
    "STATE_COUNT",
    "DriveConstants",
    "Supply",
    "constants",
    "energy",
    "energy_rate",
    "holds_oil",
    "in_use",
    "initial_state",
    "node_pressure",
    "stiffness",
    "supply",
)
