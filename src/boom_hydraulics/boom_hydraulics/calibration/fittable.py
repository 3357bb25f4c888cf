"""Which parameters a calibration can fit, why the others cannot, and the bounds of a fit.

A fitted parameter is a number of the plant that a re-simulation of the same commands can
tell from the recorded signals. Not fitted:

- choices and lists (``mode``, ``load_holding_valve``, the ``command_*`` lists): not numbers;
- the solver (``time_step_s``, ``substeps``, ``rtol``, ``atol_scale``): how the equations are
  integrated, not the machine;
- the controller (``control_*``): the machine's own program, known exactly; a re-simulation
  runs it as it is;
- the scenario (``command_*``): a re-simulation takes its commands from the bag;
- the kinematic chain (``a_m``, ``b_m``, ``support_height_m``, ``boom_length_m``, the stroke
  ``cylinder_min_length_m``, ``cylinder_max_length_m``): they fix the URDF and what the
  recorded rod position means; measure them;
- the start (``initial_length_m``, ``initial_velocity_m_s``): where the run began, not a
  property of the machine;
- ``gravity_m_s2``: not the machine's.

``orifice_diameter_m``, ``discharge_coefficient`` and ``density_kg_m3`` enter the model only as
K = mu pi D^2 / 4 sqrt(2 / rho) (eq. 14, 17): no signal tells them apart, so at most one of
them is fitted at a time.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence

from ..errors import ConfigError
from ..model.parameters import NAMES, Parameters, describe, group_of

CHAIN = ("a_m", "b_m", "support_height_m", "boom_length_m", "cylinder_min_length_m", "cylinder_max_length_m")
START = ("initial_length_m", "initial_velocity_m_s")
#: Why each group of parameters cannot be fitted.
_GROUP_REASONS = {
    "solver": "it sets how the equations are integrated, not the machine",
    "controller": "the controller's settings are the machine's program, known exactly",
    "scenario": "a re-simulation takes its commands from the bag",
}
#: Parameters that enter the model only as one product: fit one of them.
ORIFICE = ("orifice_diameter_m", "discharge_coefficient", "density_kg_m3")
#: Pairs the parameters' checks keep in order (lower, upper, strictly): a fitted one is bounded by
#: its partner where that is not fitted too.
ORDERED = (
    ("coulomb_friction_n", "static_friction_n", False),
    ("supply_pressure_pa", "relief_pressure_pa", False),
    ("tank_pressure_pa", "supply_pressure_pa", True),
    ("cavitation_pressure_pa", "tank_pressure_pa", True),
    ("rod_diameter_m", "piston_diameter_m", True),
)
#: A fitted value keeps this fraction of itself clear of an exclusive bound.
CLEARANCE = 1e-6


def why_not_fitted(name: str) -> str | None:
    """Why parameter ``name`` cannot be fitted, or None if it can."""
    meta = describe(name)
    group = group_of(name)
    if group in _GROUP_REASONS:
        return _GROUP_REASONS[group]
    if meta["type"] != "float":
        return "it is a choice, not a number"
    if name in CHAIN:
        return "it is part of the kinematic chain (the URDF and what the recorded rod position means); measure it"
    if name in START:
        return "it is where the run started, not a property of the machine"
    if name == "gravity_m_s2":
        return "it is not the machine's"
    return None


def fittable() -> tuple[str, ...]:
    """Every parameter a calibration can fit."""
    return tuple(name for name in NAMES if why_not_fitted(name) is None)


def check_fit(names: Sequence[str]) -> None:
    """ConfigError, in one line, for a name that is no parameter, cannot be fitted or is given
    twice, and for more than one of the orifice's product."""
    if not names:
        raise ConfigError("--fit names no parameter; e.g. --fit bulk_modulus_pa,orifice_diameter_m")
    for name in names:
        if name not in NAMES:
            close = difflib.get_close_matches(name, NAMES, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise ConfigError(f"--fit {name}: unknown parameter{hint}")
        reason = why_not_fitted(name)
        if reason is not None:
            raise ConfigError(f"--fit {name}: cannot be fitted: {reason}")
    if len(set(names)) != len(names):
        raise ConfigError(f"--fit names a parameter twice: {', '.join(names)}")
    product = [n for n in names if n in ORIFICE]
    if len(product) > 1:
        raise ConfigError(
            f"--fit {', '.join(product)}: these enter the model only as K = mu pi D^2/4 sqrt(2/rho) (eq. 14, 17), "
            "so no signal tells them apart; fit one of them"
        )


def bounds(name: str, p: Parameters, fitted: Sequence[str]) -> tuple[float, float]:
    """(low, high) of a fit of ``name``: its own range (an exclusive bound kept CLEARANCE of the
    start value clear), narrowed by the partner of an ordered pair that is not fitted too."""
    meta = describe(name)
    start = getattr(p, name)
    low = meta["low"] if meta["low"] is not None else -float("inf")
    high = meta["high"] if meta["high"] is not None else float("inf")
    if not meta["low_inclusive"]:
        low += CLEARANCE * abs(start)
    for lower, upper, strict in ORDERED:
        gap = CLEARANCE if strict else 0.0
        if name == lower and upper not in fitted:
            high = min(high, getattr(p, upper) * (1.0 - gap))
        if name == upper and lower not in fitted:
            low = max(low, getattr(p, lower) * (1.0 + gap))
    return low, high
