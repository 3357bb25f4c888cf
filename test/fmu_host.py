"""An FMI host for the tests: runs an exported FMU through fmpy in a process of its own and
prints what it saw as one JSON document on stdout.

    python test/fmu_host.py FMU [--set NAME=VALUE ...] [--path FOLDER]

``--path`` puts FOLDER first on the module search path before fmpy is imported: run as
``python -I -S test/fmu_host.py FMU --path FOLDER`` with FOLDER holding fmpy and what it
needs alone (test/fmpy_alone.py), the FMU runs in a Python with nothing else installed, as
a host that has never seen boom_hydraulics has it; ``isolated`` tells which of numba,
boom_hydraulics and yaml that Python could import.

Scenarios, each on fresh instances of the FMU: ``validate`` (fmpy's check of the model
description), ``cycle`` (lift 3 s, hold 2 s, lower 3 s, hold 1 s at communication steps
of STEP_S), ``cycle_set`` (the same with the parameters of --set given through FMI
before initialization), ``cycle_force`` (the same with the external rod force input held
at FORCE_CYCLE_N), ``payload`` (a payload taken on while the boom holds), ``external_force``
(an external rod force put on the rod while the boom holds),
``tunable`` (a parameter set between two steps), ``refusals`` (steps the FMU must refuse,
and what it logged) and ``lifecycle`` (reset and terminate).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from collections.abc import Callable
from ctypes import byref, c_char_p, c_int, c_void_p
from typing import Any

if __name__ == "__main__" and "--path" in sys.argv:  # before fmpy is imported (see the docstring)
    sys.path.insert(0, sys.argv[sys.argv.index("--path") + 1])

from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
    fmi2Terminated,
)
from fmpy.logging import addLoggerProxy
from fmpy.validation import validate_fmu

#: The communication step of the runs, s (ten of the default config's time steps).
STEP_S = 0.01
#: The valve command of the lift-hold-lower cycle: (until s, opening).
CYCLE = ((3.0, 1.0), (5.0, 0.0), (8.0, -1.0), (9.0, 0.0))
OUTPUTS = ("q1", "v", "f_hyd", "p1", "p2", "alpha", "power", "supply_energy")
#: The external rod force of the cycle_force scenario, N (negative: it pushes the rod in, a heavier load).
FORCE_CYCLE_N = -2000.0
#: The external rod force put on the held boom in the external_force scenario, N (extending: it helps hold).
FORCE_HELD_N = 2000.0
#: Values set between two steps that the model refuses, on their own or together with the
#: others (model/parameters.py), each case with its values: the FMU must refuse them too.
MODEL_REFUSALS = {
    "below_range": {"piston_diameter_m": -0.04},
    "above_range": {"viscous_friction_n_s_m": 1.0e9},
    "not_a_choice": {"load_holding_valve": "sideways"},
    "rod_wider_than_piston": {"rod_diameter_m": 0.05},
    "support_above_b": {"support_height_m": 1.45},
    "stroke_outside_triangle": {"cylinder_max_length_m": 1.8},
    "initial_length_outside_stroke": {"cylinder_min_length_m": 1.38},
    "supply_at_tank": {"supply_pressure_pa": 1.0e5},
    "relief_below_supply": {"relief_pressure_pa": 15.0e6},
    "cavitation_at_tank": {"cavitation_pressure_pa": 1.0e5},
    "breakaway_below_coulomb": {"static_friction_n": 90.0},
}


class Host:
    """One FMU's instances, with their log messages kept."""

    def __init__(self, path: str) -> None:
        self.description = read_model_description(path)
        self.folder = extract(path)
        self.refs = {v.name: v.valueReference for v in self.description.modelVariables}
        self.types = {v.name: v.type for v in self.description.modelVariables}
        self.messages: list[str] = []

        def log(env: c_void_p, name: c_char_p, status: c_int, category: c_char_p, message: c_char_p) -> None:
            self.messages.append(message.decode())

        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(self.callbacks))  # formats the variadic message before it reaches log()

    def instance(self, parameters: dict[str, Any] | None = None, start_s: float = 0.0) -> FMU2Slave:
        """A new instance, initialized with ``parameters`` set before."""
        fmu = FMU2Slave(
            guid=self.description.guid,
            unzipDirectory=self.folder,
            modelIdentifier=self.description.coSimulation.modelIdentifier,
            instanceName="boom",
        )
        fmu.instantiate(callbacks=self.callbacks, loggingOn=True)
        self.start(fmu, parameters, start_s)
        return fmu

    def start(self, fmu: FMU2Slave, parameters: dict[str, Any] | None, start_s: float = 0.0) -> None:
        fmu.setupExperiment(startTime=start_s)
        fmu.enterInitializationMode()
        for name, value in (parameters or {}).items():
            self.set(fmu, name, value)
        fmu.exitInitializationMode()

    def set(self, fmu: FMU2Slave, name: str, value: Any) -> None:
        ref = [self.refs[name]]
        {"Real": fmu.setReal, "Integer": fmu.setInteger, "String": fmu.setString}[self.types[name]](ref, [value])

    def get(self, fmu: FMU2Slave, name: str) -> Any:
        value = {"Real": fmu.getReal, "Integer": fmu.getInteger, "String": fmu.getString}[self.types[name]](
            [self.refs[name]]
        )[0]
        return value.decode() if isinstance(value, bytes) else value

    def outputs(self, fmu: FMU2Slave) -> list[float]:
        return fmu.getReal([self.refs[name] for name in OUTPUTS])

    def run(self, fmu: FMU2Slave, until_s: float, opening: Callable[[float], float], t: float = 0.0) -> list:
        """Steps of STEP_S from ``t`` to ``until_s``: rows of t and the outputs after each."""
        rows = []
        for k in range(round((until_s - t) / STEP_S)):
            now = t + k * STEP_S
            fmu.setReal([self.refs["valve_command"]], [opening(now)])
            fmu.doStep(now, STEP_S)
            rows.append([now + STEP_S, *self.outputs(fmu)])
        return rows

    def refused(self, call: Callable[[], None]) -> dict[str, Any]:
        """The status of a call that should be refused, and the message it logged."""
        before = len(self.messages)
        try:
            call()
        except FMICallException as exc:
            return {"status": exc.status, "message": " ".join(self.messages[before:])}
        return {"status": 0, "message": " ".join(self.messages[before:])}


def cycle_opening(t: float) -> float:
    return next((u for end, u in CYCLE if t < end - 1e-9), 0.0)


def cycle(host: Host, parameters: dict[str, Any]) -> dict[str, Any]:
    fmu = host.instance(parameters)
    rows = [[0.0, *host.outputs(fmu)], *host.run(fmu, CYCLE[-1][0], cycle_opening)]
    fmu.terminate()
    fmu.freeInstance()
    return {"columns": ["t", *OUTPUTS], "rows": rows}


def payload(host: Host) -> dict[str, Any]:
    """Lift for 1 s, hold 3 s, take on 100 kg more, hold 3 s: the rows of each hold's last second."""
    fmu = host.instance()
    host.run(fmu, 1.0, lambda t: 1.0)
    held = host.run(fmu, 4.0, lambda t: 0.0, t=1.0)[-100:]
    host.set(fmu, "payload_mass_kg", 150.0)
    loaded = host.run(fmu, 7.0, lambda t: 0.0, t=4.0)[-100:]
    fmu.terminate()
    fmu.freeInstance()
    return {"held": held, "loaded": loaded}


def external_force(host: Host) -> dict[str, Any]:
    """Lift for 1 s, hold 3 s, push the rod out with FORCE_HELD_N, hold 3 s: the rows of each hold's last second."""
    fmu = host.instance()
    host.run(fmu, 1.0, lambda t: 1.0)
    held = host.run(fmu, 4.0, lambda t: 0.0, t=1.0)[-100:]
    host.set(fmu, "f_ext", FORCE_HELD_N)
    pushed = host.run(fmu, 7.0, lambda t: 0.0, t=4.0)[-100:]
    fmu.terminate()
    fmu.freeInstance()
    return {"held": held, "pushed": pushed}


def tunable(host: Host) -> dict[str, Any]:
    """Lift for 0.5 s, then at 10 MPa supply pressure (set between two steps) for 0.5 s more."""
    fmu = host.instance()
    before = host.run(fmu, 0.5, lambda t: 1.0)[-1]
    host.set(fmu, "supply_pressure_pa", 10.0e6)
    after = host.run(fmu, 1.0, lambda t: 1.0, t=0.5)[-1]
    fmu.terminate()
    fmu.freeInstance()
    return {"before": before, "after": after}


def refusals(host: Host) -> dict[str, Any]:
    fmu = host.instance()
    host.run(fmu, 0.5, lambda t: 1.0)
    before = host.outputs(fmu)
    result: dict[str, Any] = {"before": before}
    result["odd_step"] = host.refused(lambda: fmu.doStep(0.5, 0.0015))
    result["odd_step"]["last_successful_s"] = fmu.getRealStatus(fmi2LastSuccessfulTime)
    result["odd_step"]["terminated"] = fmu.getBooleanStatus(fmi2Terminated)
    result["odd_step"]["after"] = host.outputs(fmu)
    result["wrong_time"] = host.refused(lambda: fmu.doStep(0.7, STEP_S))
    result["zero_step"] = host.refused(lambda: fmu.doStep(0.5, 0.0))
    host.set(fmu, "valve_command", math.nan)
    result["nan_command"] = host.refused(lambda: fmu.doStep(0.5, STEP_S))
    host.set(fmu, "valve_command", 1.0)
    host.set(fmu, "f_ext", math.nan)
    result["nan_force"] = host.refused(lambda: fmu.doStep(0.5, STEP_S))
    host.set(fmu, "f_ext", 0.0)
    host.set(fmu, "piston_diameter_m", -0.04)
    result["bad_parameter"] = host.refused(lambda: fmu.doStep(0.5, STEP_S))
    host.set(fmu, "piston_diameter_m", 0.04)
    result["model"] = {}
    for case, values in MODEL_REFUSALS.items():
        kept = {name: host.get(fmu, name) for name in values}
        for name, value in values.items():
            host.set(fmu, name, value)
        result["model"][case] = host.refused(lambda: fmu.doStep(0.5, STEP_S))
        for name, value in kept.items():
            host.set(fmu, name, value)
    host.set(fmu, "time_step_s", 0.002)
    result["fixed_parameter"] = host.refused(lambda: fmu.doStep(0.5, STEP_S))
    result["after_refusals"] = host.outputs(fmu)
    host.set(fmu, "time_step_s", 0.001)
    result["drifted"] = host.refused(lambda: fmu.doStep(0.5 + 2e-8, STEP_S))  # a host's sum of steps
    result["set_method"] = host.refused(lambda: host.set(fmu, "method", "euler"))
    result["set_method"]["method"] = host.get(fmu, "method")
    before_drive = host.outputs(fmu)
    host.set(fmu, "drive", "fixed_pump")
    result["drive"] = host.refused(lambda: fmu.doStep(0.51, STEP_S))
    result["drive"]["after"] = host.outputs(fmu)
    result["drive"]["before"] = before_drive
    fmu.terminate()
    fmu.freeInstance()
    # a time step so small that no step size is a number of them the FMU takes
    fmu = host.instance({"time_step_s": 1e-300})
    result["tiny_time_step"] = host.refused(lambda: fmu.doStep(0.0, STEP_S))
    fmu.terminate()
    fmu.freeInstance()
    # a drive chosen before initialization is the one that runs
    fmu = host.instance({"drive": "fixed_pump"})
    host.run(fmu, 0.5, lambda t: 1.0)
    result["fixed_pump"] = host.outputs(fmu)
    fmu.terminate()
    fmu.freeInstance()
    # a step the simulation cannot finish: end stops this stiff need more substeps than it takes
    fmu = host.instance({"time_step_s": 0.01, "end_stop_damping_n_s_m2": 1.0e15})
    start = host.outputs(fmu)
    host.set(fmu, "valve_command", 1.0)
    result["too_stiff"] = host.refused(lambda: fmu.doStep(0.0, 3.0))
    result["too_stiff"]["last_successful_s"] = fmu.getRealStatus(fmi2LastSuccessfulTime)
    result["too_stiff"]["start"], result["too_stiff"]["after"] = start, host.outputs(fmu)
    fmu.doStep(0.0, 1.0)  # a shorter step from where the refused one started
    result["too_stiff"]["shorter"] = host.outputs(fmu)
    fmu.terminate()
    fmu.freeInstance()
    return result


def lifecycle(host: Host) -> dict[str, Any]:
    fmu = host.instance({"supply_pressure_pa": 12.0e6})
    first = host.run(fmu, 1.0, lambda t: 1.0)[-1]
    fmu.reset()
    supply_after_reset = fmu.getReal([host.refs["supply_pressure_pa"]])[0]
    host.start(fmu, {"supply_pressure_pa": 12.0e6})
    again = host.run(fmu, 1.0, lambda t: 1.0)[-1]
    fmu.reset()
    host.start(fmu, {})
    default = host.run(fmu, 1.0, lambda t: 1.0)[-1]
    fmu.terminate()
    after_terminate = host.refused(lambda: fmu.doStep(1.0, STEP_S))
    fmu.freeInstance()
    return {
        "first": first,
        "again": again,
        "default": default,
        "supply_after_reset": supply_after_reset,
        "after_terminate": after_terminate,
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("fmu")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--path", help="a folder to import fmpy from, first on the search path")
    args = parser.parse_args()
    parameters = {}
    for assignment in args.set:
        name, _, value = assignment.partition("=")
        parameters[name] = float(value)
    host = Host(args.fmu)
    report = {
        "isolated": {name: importlib.util.find_spec(name) is not None for name in ("numba", "boom_hydraulics", "yaml")},
        "validate": validate_fmu(args.fmu),
        "cycle": cycle(host, {}),
        "cycle_set": cycle(host, parameters),
        "cycle_force": cycle(host, {"f_ext": FORCE_CYCLE_N}),
        "payload": payload(host),
        "external_force": external_force(host),
        "tunable": tunable(host),
        "refusals": refusals(host),
        "lifecycle": lifecycle(host),
    }
    json.dump(report, sys.stdout)


if __name__ == "__main__":
    main()
