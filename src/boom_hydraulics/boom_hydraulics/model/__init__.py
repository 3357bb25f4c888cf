"""The drive model: parameters and params files, the elements with their equations, the models.

A model is a module with the functions of :class:`Model`; :data:`MODELS` names them all.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, Protocol, runtime_checkable

from . import paper, physical
from .parameters import MODES, Parameters


@runtime_checkable
class Model(Protocol):
    """What every model offers: its state, its constants, its derivative and its outputs."""

    STATE_NAMES: tuple[str, ...]  # the components of y, in order
    STATE_SCALES: tuple[str, ...]  # the scale of each component for error control (length, pressure, ...)
    ENERGY_STATES: tuple[int, int] | None  # indices of W = integral of dH/dt and of |dH/dt|, or None
    STABILITY_BOUND: bool  # whether the stepping takes the substeps stiffness_rate asks for

    def constants(self, p: Parameters) -> Any:
        """Everything the derivative needs from the parameters, computed once (a NamedTuple)."""
        ...

    def initial_state(self, p: Parameters, q1_m: float | None = None) -> list[float]:
        """The state at rest at cylinder length ``q1_m`` (default: the parameters' q1(0))."""
        ...

    def derivative(self, t: float, y: list, c: Any, u: Any, xp: ModuleType = math) -> list:
        """dy/dt at time ``t`` with valve command ``u`` (floats, or numpy arrays with xp=numpy)."""
        ...

    def energy(self, y: list, c: Any, xp: ModuleType = math) -> Any:
        """H, the stored energy whose change the state's W must match (the energy balance), J."""
        ...

    def stiffness_rate(self, y: list, c: Any, u: Any, dt: float, xp: ModuleType = math) -> Any:
        """An estimate of the Jacobian's largest eigenvalue magnitude over the next ``dt``, 1/s."""
        ...

    def outputs(self, t: float, y: list, c: Any, u: Any, xp: ModuleType = math) -> tuple:
        """Every output as a tuple in the order of outputs.OUTPUT_NAMES (flags 1.0 or 0.0)."""
        ...

    def samples(self, t: float, y: list, c: Any, u: Any, xp: ModuleType = math) -> tuple:
        """The outputs of outputs.SAMPLE_NAMES alone (what the run metrics take), as outputs gives them."""
        ...

    def with_payload(self, c: Any, share: Any) -> Any:
        """The constants ``c`` with ``share`` of payload_mass_kg on the hook (the payload schedule)."""
        ...

    def observe(self, t: float, y: list, c: Any, u: Any, xp: ModuleType = math) -> dict[str, Any]:
        """Every output (solve.simulation.OUTPUTS) at this state and command."""
        ...


#: Every model, by the name of its mode (the one registry of them).
MODELS: dict[str, Model] = {"physical": physical, "paper": paper}
assert tuple(MODELS) == MODES, "parameters.MODES must name the registered models"
