"""The model's parameters through the Foxglove protocol's parameters capability.

Every model parameter the node declares (the plant, solver and controller groups; not the
headless scenario, nor what no solver reads yet) is a protocol parameter of the same name
and value; those the schema marks start-only are refused at run time, as the node's are. A client's set is
checked as a whole, as the node's ``on_set`` checks it (:func:`~..model.parameters.from_mapping`:
types, ranges, the geometry's cross-checks): either every value of it applies, or none
does and the run stays as it was, with the one line that says why. A whole number given
for a float parameter (Foxglove sends ``120`` for ``120.0``) is taken as that float.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from foxglove import Parameter, ParameterType

from ..errors import ConfigError
from ..model.parameters import NAMES, UNSOLVED, Parameters, describe, from_mapping, group_of

#: The parameters a live run offers: the node's model parameters (not the scenario group,
#: not those no solver reads yet).
OFFERED = tuple(name for name in NAMES if group_of(name) != "scenario" and name not in UNSOLVED)
#: rcl_interfaces/msg/ParameterType of each kind, for the bag's /parameter_events.
ROS_TYPES = {"float": 3, "int": 2, "str": 4, "list": 8}


def protocol_parameter(name: str, value: Any) -> Parameter:
    """``name`` = ``value`` as the protocol carries it: floats typed float64 (so that 120.0
    stays a float on the wire), lists of floats float64_array."""
    kind = describe(name)["type"]
    if kind == "float":
        return Parameter(name, value=float(value), type=ParameterType.Float64)
    if kind == "list":
        return Parameter(name, value=[float(v) for v in value], type=ParameterType.Float64Array)
    return Parameter(name, value=value)


def current(params: Parameters, names: Iterable[str] = ()) -> list[Parameter]:
    """The offered parameters named (all of them for none) at their values in ``params``;
    names not offered are left out, as the protocol asks."""
    wanted = list(names) or list(OFFERED)
    return [protocol_parameter(n, getattr(params, n)) for n in wanted if n in OFFERED]


def checked(params: Parameters, requested: Iterable[Parameter]) -> Parameters:
    """The parameters after a client's set, all of it checked at once. Raises ConfigError,
    one line, for a name not offered, an unset, or a value the model refuses."""
    changes: dict[str, Any] = {}
    for p in requested:
        if p.name not in OFFERED:
            hint = " (the command_* scenario belongs to boom-sim run)" if p.name in NAMES else ""
            raise ConfigError(f"unknown parameter '{p.name}' for boom-sim live{hint}")
        if describe(p.name)["start_only"]:
            raise ConfigError(
                f"parameter '{p.name}' applies at start only: give it with --set {p.name}=... and start again"
            )
        value = p.get_value()
        if value is None:
            raise ConfigError(f"parameter '{p.name}' cannot be unset; give it a value")
        changes[p.name] = value
    return from_mapping(changes, base=params)


def events(params: Parameters, names: Iterable[str]) -> list[tuple[str, int, Any]]:
    """(name, ROS parameter type, value in ``params``) of each parameter a set named, as the
    node records the change on /parameter_events."""
    return [(n, ROS_TYPES[describe(n)["type"]], getattr(params, n)) for n in names]
