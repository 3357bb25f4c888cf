"""The drives that feed the cylinder, one module each, behind one parameter (``drive``).

Every drive has one state (:data:`STATE_NAMES` of its module), so that they share one state
layout, and offers ``initial_state(d)`` and ``supply(...)``: the rate of its state, the
pump's operating point and its supply-side ledger terms (:class:`Supply`). The valve drives
(``VALVE``: pressure_compensated, fixed_pump, load_sensing) also give ``port_pressure_pa``,
what the 4/3 valve's P port sees; pump_controlled gives ``ports``, the flows into the
chambers, in place of the valve. The electric chain from the pump's shaft to the battery
and the energy ledger are the same for all (:mod:`..ledger`).

Equations and conventions: docs/model.md, section "Drives".
"""

from __future__ import annotations

from types import ModuleType

from ...jit import jitable
from ..parameters import DRIVES as DRIVE_CHOICES
from . import fixed_pump, load_sensing, pressure_compensated, pump_controlled
from .constants import DriveConstants, Supply, constants

#: Every drive, by the name the ``drive`` parameter gives it (the one registry of them).
DRIVES: dict[str, ModuleType] = {
    "pressure_compensated": pressure_compensated,
    "fixed_pump": fixed_pump,
    "load_sensing": load_sensing,
    "pump_controlled": pump_controlled,
}
assert tuple(DRIVES) == DRIVE_CHOICES, "parameters.DRIVES must name the registered drives"


@jitable
def initial_state(drive: str, d: DriveConstants) -> float:
    """``DRIVES[drive].initial_state(d)``, as compiled code can call it too (numba picks no
    function from a dict of modules): the registered drives, in their order."""
    if drive == "pressure_compensated":
        return pressure_compensated.initial_state(d)
    if drive == "fixed_pump":
        return fixed_pump.initial_state(d)
    if drive == "load_sensing":
        return load_sensing.initial_state(d)
    if drive == "pump_controlled":
        return pump_controlled.initial_state(d)
    raise ValueError("no drive of that name")  # parameters.DRIVES names the registered ones


__all__ = ("DRIVES", "DriveConstants", "Supply", "constants", "initial_state")
