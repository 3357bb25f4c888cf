"""The co-simulation slave an exported FMU runs: the physical drive stepped by its Simulator.

pythonfmu's binary calls this class for every FMI function. A communication step of h
seconds takes h / time_step_s steps of the same compiled kernel boom-sim and the node
step (solve.simulation.Simulator.step: the stability-bound substeps and the energy
guard), with the valve command, the payload and the external rod force held over the step.

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
    EXTERNAL_FORCE_PARAMETER,
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
from .units import base_exponents, base_factor, unit_name

#: How far, as a fraction of the time step, a step size may be off a whole number of time
#: steps (a host that takes differences of its communication points rounds them).
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
    ConfigError when it does not start where ``sim`` is or is not a whole number of steps.

    A host that adds up its step sizes drifts off the FMU's time (by 1.7e-8 s after 10^6
    steps of 1 ms, as fmi_adapter steps): a communication point within half a time step of
    the FMU's time is taken as that time, as a stamped command takes effect at the step that
    starts within half a step of it."""
    dt = sim.params.time_step_s
    if not abs(offset_s - sim.t) < 0.5 * dt:
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
        self.f_ext = self.exported.external_rod_force_n  # the input interface.EXTERNAL_FORCE
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
        defined = {unit_name(v.unit): v.unit for v in VARIABLES if v.kind == "float"}
        for name, unit in sorted(defined.items()):
            node = SubElement(units, "Unit", name=name)
            exponents, factor = base_exponents(unit), base_factor(unit)
            if exponents:
                attributes = {base: str(n) for base, n in exponents.items()}
                if factor != 1.0:
                    attributes["factor"] = repr(factor)
                SubElement(node, "BaseUnit", attributes)
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
        """The parameters in effect with what was set through FMI and the payload and
        external-force inputs (the same object when nothing changed); ConfigError naming a refused value, or a fixed
        parameter set to another value after initialization."""
        changes = {name: value for name, value in self.changes.items() if value != getattr(self.params, name)}
        if self.payload_mass_kg != self.params.payload_mass_kg:
            changes[PAYLOAD] = self.payload_mass_kg
        if self.f_ext != self.params.external_rod_force_n:
            changes[EXTERNAL_FORCE_PARAMETER] = self.f_ext
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
    """Where this process loaded the FMU's Linux binary, have the C library release
    pythonfmu's state in it (its exported ``finalizePythonInterpreter``) at exit, before the
    binary's own exit handlers run.

    pythonfmu's binary (0.7.0) is never unloaded (it holds STB_GNU_UNIQUE symbols), so at
    exit its global ``std::shared_ptr`` is destroyed (a static destructor) and then released
    again by the library's destructor function: a double free, found with valgrind. It
    aborted an fmpy host in 4 of 8 runs ("corrupted double-linked list") and a C host in 5
    of 5 ("corrupted unsorted chunks"). Released first (exit handlers run last registered
    first), both find it empty. The binary is pinned (RTLD_NODELETE) so that the handler's
    code stays mapped; nothing is done where it is not loaded (the exporting process).
    """
    if sys.platform != "linux" or binary in _RELEASED:
        return
    try:
        library = ctypes.CDLL(str(binary), mode=os.RTLD_NOW | os.RTLD_NOLOAD | os.RTLD_NODELETE)
    except OSError:
        return
    _RELEASED.add(binary)
    register = ctypes.CDLL(None).__cxa_atexit
    register.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    register(ctypes.cast(library.finalizePythonInterpreter, ctypes.c_void_p), None, None)
