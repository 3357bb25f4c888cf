"""What the FMU shows a host: its inputs, outputs and parameters, each with unit, range and description.

- Inputs: the valve command, the payload mass and the external rod force (held over each
  communication step).
- Outputs: rod position, velocity and force, both chamber pressures, boom angle, supply
  power and energy, under the names boom-sim's CSV columns have (model.outputs).
- Parameters: every plant parameter the solvers read, with its unit (tunable: a new value
  applies from the next communication step on), and the solver's time step and substeps,
  the drive and the initial rod state (fixed: set before initialization); the method, which
  the host reads but cannot set (its step is compiled in at export).

The mode is physical (the corrected drive), and the payload and the external rod force
(``f_ext``, the model's ``external_rod_force_n``) are inputs, so none of them is a
parameter. Ranges are the model's own (parameters.py); an exclusive lower bound (a diameter
> 0) is not written as an FMI ``min``, which is inclusive, and is refused at the bound
itself like any value out of range.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..model.outputs import OUTPUTS as MODEL_OUTPUTS
from ..model.parameters import UNSOLVED, Parameters, describe, names_in
from ..solve.integrators import FIXED_STEP

#: The FMU's model identifier: the name of its binary and of its model.
MODEL_IDENTIFIER = "boom_drive"
#: The file the FMU carries in its resources folder: the parameters it was exported with (a
#: ROS 2 params YAML, as boom-sim reads it), for a person to read; the binary holds them too.
PARAMETERS_FILE = "boom_drive.yaml"

VALVE_COMMAND = "valve_command"
PAYLOAD = "payload_mass_kg"
#: The input of the external rod force, and the model parameter it sets.
EXTERNAL_FORCE = "f_ext"
EXTERNAL_FORCE_PARAMETER = "external_rod_force_n"


@dataclass(frozen=True)
class Variable:
    """One variable of the FMU: its name, causality, type, unit (the model's spelling, ''
    dimensionless), description, variability and inclusive range."""

    name: str
    causality: str  # "input", "output", "parameter" or "calculatedParameter"
    kind: str  # "float", "int" or "str"
    unit: str
    description: str
    variability: str = "continuous"  # parameters: "fixed" or "tunable"
    low: float | None = None
    high: float | None = None


INPUTS = (
    Variable(
        VALVE_COMMAND,
        "input",
        "float",
        "1",
        "Valve command: spool opening from -1 (lower) to 1 (lift), clamped to that range; held over each "
        "communication step (zero-order hold, as boom-sim holds it over each time step)",
        low=-1.0,
        high=1.0,
    ),
    Variable(
        PAYLOAD,
        "input",
        "float",
        "kg",
        describe(PAYLOAD)["description"] + "; a new value applies from the next communication step on",
        low=0.0,
        high=describe(PAYLOAD)["high"],
    ),
    Variable(
        EXTERNAL_FORCE,
        "input",
        "float",
        "N",
        describe(EXTERNAL_FORCE_PARAMETER)["description"]
        + "; the force a mechanical network puts on the rod, held over each communication step",
        low=describe(EXTERNAL_FORCE_PARAMETER)["low"],
        high=describe(EXTERNAL_FORCE_PARAMETER)["high"],
    ),
)

#: The outputs, by the model's names: rod position, velocity and force, the pressures, the
#: boom angle, supply power and energy.
OUTPUT_NAMES = ("q1", "v", "f_hyd", "p1", "p2", "alpha", "power", "supply_energy")
_MODEL_OUTPUTS = {name: (unit, description) for name, unit, description in MODEL_OUTPUTS}
OUTPUTS = tuple(Variable(name, "output", "float", *_MODEL_OUTPUTS[name]) for name in OUTPUT_NAMES)

#: Parameters that only take effect at initialization: the solver's, the drive (the circuit, and
#: with it the meaning of the drive's state) and the initial rod state.
FIXED = ("method", "time_step_s", "substeps", "drive", "initial_length_m", "initial_velocity_m_s")
#: Plant parameters that are not FMU parameters: the mode is physical, the payload and the
#: external rod force inputs, and the drives' parameters that no solver reads yet (as the
#: node does not declare them).
NOT_PARAMETERS = ("mode", PAYLOAD, EXTERNAL_FORCE_PARAMETER, *UNSOLVED)


#: Parameters the FMU shows but a host cannot set (causality calculatedParameter): the method,
#: whose step is compiled into the binary at export.
CALCULATED = ("method",)


def _parameter(name: str) -> Variable:
    meta = describe(name)
    low = meta["low"] if meta["low_inclusive"] else None
    return Variable(
        name,
        "calculatedParameter" if name in CALCULATED else "parameter",
        meta["type"],
        meta["unit"],
        meta["description"],
        "fixed" if name in FIXED else "tunable",
        low,
        meta["high"],
    )


PARAMETERS = tuple(
    _parameter(name) for name in (*names_in("plant"), "method", "time_step_s", "substeps") if name not in NOT_PARAMETERS
)

#: Every variable, in the order of their value references.
VARIABLES = (*INPUTS, *OUTPUTS, *PARAMETERS)


def unsupported(params: Parameters) -> str | None:
    """Why the FMU cannot run ``params`` (None: it can): it is the physical drive, stepped by
    the compiled fixed-step loop."""
    if params.mode != "physical":
        return f"the FMU is the physical drive; mode is {params.mode!r}: set mode: physical"
    if params.method not in FIXED_STEP:
        return f"method {params.method!r} has no fixed step for the FMU to take; choose one of {', '.join(FIXED_STEP)}"
    return None
