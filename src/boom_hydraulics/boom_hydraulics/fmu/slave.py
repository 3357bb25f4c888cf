"""The co-simulation slave an exported FMU runs: the physical drive stepped by its Simulator.

pythonfmu's binary calls this class for every FMI function. A communication step of h
seconds takes h / time_step_s steps of the same compiled kernel boom-sim and the node
step (solve.simulation.Simulator.step: the stability-bound substeps and the energy
guard), with the valve command and the payload held over the step.

A step the drive cannot take is refused as FMI 2.0 says (fmi2DoStep returns fmi2Discard,
pythonfmu's status for a do_step that returns False): a step that does not start where the
FMU is, a step size that is not a whole number of time steps, a value out of range, or a
step the simulation cannot finish (energy balance broken, too stiff, rod out of the
geometry). The FMU then stays at the start of that step (fmi2LastSuccessfulTime), and the
reason is logged in one line. Errors never escape as exceptions, which pythonfmu turns
into fmi2Fatal.

fmi2Reset makes pythonfmu build a new instance: the exported parameters, at rest.
"""

from __future__ import annotations

import atexit
import ctypes
import math
import os
import sys
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from ..errors import BoomHydraulicsError, ConfigError, SimulationError
from ..model import config
from ..model.parameters import Parameters, from_mapping
from ..solve.command_queue import valve_opening
from ..solve.simulation import Simulator
from .interface import (
    FIXED,
    INPUTS,
    MODEL_IDENTIFIER,
    OUTPUT_NAMES,
    OUTPUTS,
    PARAMETERS,
    PARAMETERS_FILE,
    PAYLOAD,
    VALVE_COMMAND,
    VARIABLES,
    VARIABLES_FILE,
    Variable,
    unsupported,
)
from .units import base_exponents, unit_name

#: How far, as a fraction of the time step, a communication point or step size may be off
#: the time-step grid (a host sums its step sizes in floating point).
GRID_TOLERANCE = 1e-6


def _describe(node: Element, variable: Variable, start: Any) -> Element:
    """``node`` (a ScalarVariable) with its type element's unit, range and start value to the last bit."""
    value = node[0]  # the Real or Integer element
    if variable.kind == "float":
        value.set("unit", unit_name(variable.unit))
    cast = float if variable.kind == "float" else int
    if start is not None:
        value.set("start", repr(cast(start)))
    for attribute, bound in (("min", variable.low), ("max", variable.high)):
        if bound is not None:
            value.set(attribute, repr(cast(bound)))
    return node


class Quantity(Real):
    """A Real with its unit and range in the model description, and its start value to the
    last bit (pythonfmu's Real writes neither unit nor range, and 16 digits)."""

    def __init__(self, variable: Variable, **kwargs: Any) -> None:
        super().__init__(variable.name, description=variable.description, **kwargs)
        self.variable = variable

    def to_xml(self) -> Element:
        return _describe(super().to_xml(), self.variable, self.start)


class Count(Integer):
    """An Integer with its range in the model description."""

    def __init__(self, variable: Variable, **kwargs: Any) -> None:
        super().__init__(variable.name, description=variable.description, **kwargs)
        self.variable = variable

    def to_xml(self) -> Element:
        return _describe(super().to_xml(), self.variable, self.start)


def communication_steps(offset_s: float, step_s: float, sim: Simulator) -> int:
    """The time steps of a communication step of ``step_s`` from ``offset_s`` after the start;
    ConfigError when it does not start where ``sim`` is or is not a whole number of steps."""
    dt = sim.params.time_step_s
    if not math.isclose(offset_s, sim.t, rel_tol=0.0, abs_tol=GRID_TOLERANCE * dt):
        raise ConfigError(
            f"it starts {offset_s!r} s after the start, but the FMU is at {sim.t!r} s; "
            "step on from the last communication point"
        )
    steps = round(step_s / dt) if math.isfinite(step_s) and step_s > 0 else 0
    if steps < 1 or not math.isclose(steps * dt, step_s, rel_tol=0.0, abs_tol=GRID_TOLERANCE * dt):
        raise ConfigError(
            f"the step size is not a whole number of the drive's time steps of {dt!r} s (time_step_s); "
            "use a multiple of it"
        )
    return steps


class BoomDrive(Fmi2Slave):
    """The physical boom drive as an FMI 2.0 co-simulation slave (see the module docstring)."""

    author = "boom_hydraulics maintainers"
    license = "Apache-2.0"
    description = (
        "Hydraulic drive that lifts a crane boom (physical mode): 4/3 proportional valve, supply, "
        "two-chamber cylinder, seal friction, end stops and the boom's Lagrange dynamics"
    )

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.modelName = MODEL_IDENTIFIER
        folder = Path(self.resources or ".")
        check_variables(folder / VARIABLES_FILE)
        release_at_exit(folder.parent / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so")
        self.exported = config.load(folder / PARAMETERS_FILE)
        reason = unsupported(self.exported)
        if reason is not None:
            raise ConfigError(f"{folder / PARAMETERS_FILE}: {reason}")
        self.default_experiment = DefaultExperiment(start_time=0.0, step_size=self.exported.time_step_s)
        self.valve_command = 0.0
        self.payload_mass_kg = self.exported.payload_mass_kg
        self.params = self.exported  # the parameters in effect
        self.changes: dict[str, Any] = {}  # parameters set through FMI, in effect from the next step
        self.sim: Simulator | None = None  # from initialization to termination
        self.start_s = 0.0
        self.outputs: dict[str, float] = dict.fromkeys(OUTPUT_NAMES, math.nan)
        self.stopped = "the FMU is not initialized yet: enter and exit initialization mode first"
        for variable in INPUTS:
            self.register_variable(Quantity(variable, causality=Fmi2Causality.input), nested=False)
        for variable in OUTPUTS:
            self.register_variable(
                Quantity(variable, causality=Fmi2Causality.output, getter=self._output_getter(variable.name)),
                nested=False,
            )
        for variable in PARAMETERS:
            self.register_variable(self._parameter(variable), nested=False)

    # --- the model description ---------------------------------------------------------
    def _output_getter(self, name: str) -> Any:
        return lambda: self.outputs[name]

    def _parameter(self, variable: Variable) -> Any:
        """The pythonfmu variable of a parameter: read from what is in effect or set, set for the next step."""
        name = variable.name

        def getter() -> Any:
            return self.changes.get(name, getattr(self.params, name))

        def setter(value: Any) -> None:
            self.changes[name] = value

        variability = Fmi2Variability.fixed if variable.variability == "fixed" else Fmi2Variability.tunable
        options = {"causality": Fmi2Causality.parameter, "variability": variability, "getter": getter}
        if variable.kind == "str":
            return String(name, description=variable.description, setter=setter, **options)
        return (Quantity if variable.kind == "float" else Count)(variable, setter=setter, **options)

    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:
        """pythonfmu's model description, with the unit definitions and the initial unknowns
        (the outputs, computed at initialization) that FMI 2.0 asks for."""
        root = super().to_xml(model_options or {})
        units = Element("UnitDefinitions")
        defined = {unit_name(v.unit): base_exponents(v.unit) for v in VARIABLES if v.kind == "float"}
        for name, exponents in sorted(defined.items()):
            node = SubElement(units, "Unit", name=name)
            if exponents:
                SubElement(node, "BaseUnit", {base: str(n) for base, n in exponents.items()})
        cosimulation = root.find("CoSimulation")
        assert cosimulation is not None
        root.insert(list(root).index(cosimulation) + 1, units)
        structure = root.find("ModelStructure")
        assert structure is not None
        initial = SubElement(structure, "InitialUnknowns")
        for index, variable in enumerate(VARIABLES, start=1):
            if variable.causality == "output":
                SubElement(initial, "Unknown", index=str(index))
        return root

    # --- the FMI calls -------------------------------------------------------------------
    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        self.start_s = start_time  # the FMU's time is start_s + the Simulator's

    def exit_initialization_mode(self) -> None:
        """The drive at rest with the parameters set so far (a refusal is logged, and every
        step is then refused with it: reset the FMU and set valid values)."""
        try:
            self.params = self._next_parameters(initializing=True)
        except ConfigError as exc:
            self.stopped = f"initialization refused: {exc}"
            self.log(self.stopped, Fmi2Status.error)
            return
        self.changes.clear()
        self.sim = Simulator(self.params)
        self.stopped = ""
        self._observe()

    def do_step(self, current_time: float, step_size: float) -> bool:
        try:
            self._step(current_time, step_size)
        except BoomHydraulicsError as exc:
            self.log(f"step of {step_size!r} s from t = {current_time!r} s refused: {exc}", Fmi2Status.discard)
            return False
        return True

    def terminate(self) -> None:
        self.sim = None
        self.stopped = "the FMU is terminated: reset it to run again"

    # --- stepping ------------------------------------------------------------------------
    def _step(self, current_time: float, step_size: float) -> None:
        sim = self.sim
        if sim is None:
            raise ConfigError(self.stopped)
        steps = communication_steps(current_time - self.start_s, step_size, sim)
        params = self._next_parameters(initializing=False)
        opening = valve_opening(self.valve_command, params.mode)
        if opening is None:
            raise ConfigError(f"{VALVE_COMMAND} must be a finite opening in [-1, 1], got {self.valve_command!r}")
        if params is not self.params:
            sim.set_parameters(params)  # keeps the state; the energy balance carries on
            self.params = params
            self.changes.clear()
        before = (list(sim.y), sim.t, sim.step_count, sim.u, sim.most_substeps)
        try:
            sim.step(opening, steps)
        except SimulationError:
            sim.y, sim.t, sim.step_count, sim.u, sim.most_substeps = before  # the step is not taken
            raise
        self._observe()

    def _next_parameters(self, initializing: bool) -> Parameters:
        """The parameters in effect with what was set through FMI and the payload input (the
        same object when nothing changed); ConfigError naming a refused value."""
        changes = dict(self.changes)
        if self.payload_mass_kg != self.params.payload_mass_kg:
            changes[PAYLOAD] = self.payload_mass_kg
        if not changes:
            return self.params
        late = [name for name in changes if name in FIXED and not initializing]
        if late:
            raise ConfigError(
                f"{', '.join(late)} can only be set before initialization (variability fixed); "
                "reset the FMU to change it"
            )
        params = from_mapping(changes, base=self.params)
        reason = unsupported(params)
        if reason is not None:
            raise ConfigError(reason)
        return params

    def _observe(self) -> None:
        assert self.sim is not None
        out = self.sim.outputs()
        self.outputs = {name: float(out[name]) for name in OUTPUT_NAMES}


def check_variables(path: Path) -> None:
    """ConfigError unless the FMU's variables (its ``variables.txt``) are the ones this package
    offers, in the same order: their value references would otherwise mean other quantities."""
    try:
        exported = path.read_text(encoding="utf-8").split()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the FMU's variables ({exc.strerror})") from None
    offered = [variable.name for variable in VARIABLES]
    if exported != offered:
        raise ConfigError(
            f"this FMU was exported with other variables than the installed boom_hydraulics offers "
            f"({len(exported)} against {len(offered)}); export it again with this installation's boom-sim fmu"
        )


#: The FMU binaries whose Python state is released before this process exits.
_RELEASED: set[Path] = set()


def release_at_exit(binary: Path) -> None:
    """Where a Python process loaded the FMU's Linux binary, release pythonfmu's state in it
    (its exported ``finalizePythonInterpreter``) when Python exits, before the C exit handlers.

    pythonfmu's binary (0.7.0) is never unloaded (it holds STB_GNU_UNIQUE symbols), so at
    exit its global ``std::shared_ptr`` is destroyed and then released again by the
    library's destructor function: a double free, which aborted an fmpy host in 4 of 8 runs
    ("corrupted double-linked list"; found with valgrind). Released here first, both find it
    empty. Not in a host that is no Python (an embedded interpreter, which pythonfmu itself
    finalizes from that very destructor), nor where the binary is not loaded.
    """
    if sys.platform != "linux" or binary in _RELEASED:
        return
    try:
        python_host = os.path.realpath("/proc/self/exe") == os.path.realpath(sys.executable)
        loaded = any(str(binary) in line for line in Path("/proc/self/maps").read_text().splitlines())
    except OSError:
        return
    if python_host and loaded:
        _RELEASED.add(binary)
        atexit.register(ctypes.CDLL(str(binary)).finalizePythonInterpreter)
