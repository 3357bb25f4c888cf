"""The bridge between the model's parameters and ROS 2 parameters of the ``boom_sim`` node.

- Every model parameter the node uses (:data:`MODEL_NAMES`: the plant, solver and
  controller groups of :mod:`parameters`) and every node parameter below is declared
  with a descriptor: description with unit, type, range, and ``read_only`` for those that
  apply at start only. ``ros2 param describe`` shows all of it.
- Values are typed as the parameter is: an integer given for a float parameter (``ros2
  param set ... payload_mass_kg 120``, ``-p x:=50``, ``50`` in a params file) is taken as
  that float, and the parameter stays a double.
- A key for this node that names no parameter refuses the start, naming the closest one.
  The scenario group (``command_*``: boom-sim's and boom-sweep's headless valve command)
  is not declared: a params file may set it, for the CLI, and the node says it ignores it.
- A params file that is missing or malformed is named in one line before rclpy reads it.
"""

from __future__ import annotations

import array
import difflib
import math
import sys
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import yaml
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.parameter import Parameter

from ..errors import ConfigError
from ..model import config
from ..model.parameters import GROUPS, NAMES, UNSOLVED, describe, group_of, names_in

#: Parameters of the node itself (not of the model): name -> (default, unit, description, low, high).
NODE_PARAMETERS: dict[str, tuple[Any, str, str, float | None, float | None]] = {
    "publish_rate_hz": (100.0, "Hz", "State publish (tick) rate", 1.0, 1000.0),
    "real_time_factor": (1.0, "", "Simulated seconds per wall second; 0: as fast as possible", 0.0, 1000.0),
    "publish_clock": (False, "", "Publish /clock and stamp messages with simulated time", None, None),
    "command_timeout_s": (
        0.5,
        "s",
        "Valve returns to 0 when no command arrived for this long (simulated time); 0: never",
        0.0,
        3600.0,
    ),
    "max_catch_up_s": (
        0.2,
        "s",
        "Largest backlog a tick works off before the node gives up real-time lock",
        0.001,
        10.0,
    ),
    "jit": (
        True,
        "",
        "Step with the numba-compiled model where numba is available (about 20 s to compile the first time, "
        "then loaded from the disk cache); false: interpreted",
        None,
        None,
    ),
    "record": (True, "", "Record every published topic and received command to a bag", None, None),
    "record_folder": ("bags", "", "Folder in which each run's bag folder is created", None, None),
    "record_chunk_kib": (1024.0, "KiB", "MCAP chunk size: the most a SIGKILL can lose", 1.0, 65536.0),
    "record_flush_s": (1.0, "s", "A chunk reaches the disk at least this often: the most a SIGKILL loses", 0.05, 60.0),
    "start_paused": (False, "", "Start paused (resume with ~/pause data: false), e.g. to queue a scenario", None, None),
    "publish_robot_description": (
        True,
        "",
        "Publish the crane's URDF on robot_description (transient local); false where robot_state_publisher does",
        None,
        None,
    ),
}

#: The headless valve scenario (boom-sim, boom-sweep): the node takes its commands from topics,
#: so it declares none of these; a params file may still set them (for the CLI).
SCENARIO = names_in("scenario")
#: The model parameters the node declares and uses: every group but the scenario, and none
#: that no solver reads yet (parameters.UNSOLVED: the drives', until the kernels run them).
MODEL_NAMES = tuple(name for name in NAMES if group_of(name) != "scenario" and name not in UNSOLVED)

#: Parameters that apply at start only: read_only in their descriptors (the node's own, and
#: the model's that the schema marks start_only).
START_ONLY = frozenset(
    {
        "publish_clock",
        "jit",
        "record",
        "record_folder",
        "record_chunk_kib",
        "record_flush_s",
        "start_paused",
        "publish_robot_description",
        *(name for name in MODEL_NAMES if describe(name)["start_only"]),
    }
)

#: Parameters every rclpy node has, or may be given, beside ours.
_STANDARD = frozenset({"use_sim_time", "start_type_description_service"})
_STANDARD_PREFIXES = ("qos_overrides.",)


def _kind(name: str) -> str:
    """'float', 'int', 'bool', 'str' or 'list' (of floats) of a model or node parameter."""
    if name in NODE_PARAMETERS:
        return {float: "float", bool: "bool", str: "str"}[type(NODE_PARAMETERS[name][0])]
    return describe(name)["type"]


def default(name: str) -> Any:
    return NODE_PARAMETERS[name][0] if name in NODE_PARAMETERS else describe(name)["default"]


def descriptor(name: str) -> ParameterDescriptor:
    """The descriptor of model or node parameter ``name``: type, description with unit, range, read_only."""
    if name in NODE_PARAMETERS:
        _, unit, text, low, high = NODE_PARAMETERS[name]
        choices = None
    else:
        meta = describe(name)
        unit, text, low, high, choices = meta["unit"], meta["description"], meta["low"], meta["high"], meta["choices"]
    kind = _kind(name)
    desc = ParameterDescriptor(
        name=name,
        type=_ROS_TYPES[kind],
        description=f"{text} [{unit}]" if unit else text,
        read_only=name in START_ONLY,
    )
    if kind == "float" and low is not None and high is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high))]
    if kind == "int" and low is not None and high is not None:
        desc.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    constraints = []
    if choices:
        constraints.append(f"one of: {', '.join(choices)}")
    if name in NAMES and low is not None and not describe(name)["low_inclusive"]:
        constraints.append(f"greater than {low:g}")
    if name in START_ONLY:
        constraints.append("at start only: set it in a params file or with -p, then restart")
    desc.additional_constraints = "; ".join(constraints)
    return desc


_ROS_TYPES = {
    "float": ParameterType.PARAMETER_DOUBLE,
    "int": ParameterType.PARAMETER_INTEGER,
    "bool": ParameterType.PARAMETER_BOOL,
    "str": ParameterType.PARAMETER_STRING,
    "list": ParameterType.PARAMETER_DOUBLE_ARRAY,
}


def all_names() -> tuple[str, ...]:
    """Every parameter the node declares: the model's but the scenario, then the node's own."""
    return (*MODEL_NAMES, *NODE_PARAMETERS)


def ignored_scenario(values: Mapping[str, Any]) -> tuple[str, ...]:
    """The scenario parameters in ``values`` (a params file's and ``-p`` values for this node)
    that differ from their defaults: what the node ignores and says so once."""
    return tuple(name for name in SCENARIO if name in values and plain(values[name]) != default(name))


def plain(value: Any) -> Any:
    """A parameter value as Python: rclpy hands arrays over as ``array.array``."""
    return list(value) if isinstance(value, (array.array, tuple)) else value


def _number(value: Any) -> float | None:
    """``value`` as a float if it is an int, or a string that reads as a number; else None."""
    if isinstance(value, str):
        try:
            value = config.load_yaml(value)
        except yaml.YAMLError:
            return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def _numbers(value: Any) -> list[float] | None:
    """``value`` as a list of floats if it is a list of numbers (or of number strings), or a
    string that reads as one; else None."""
    if isinstance(value, str):
        try:
            value = config.load_yaml(value)
        except yaml.YAMLError:
            return None
    if not isinstance(value, (list, tuple, array.array)):
        return None
    numbers = [_number(v) for v in value]
    return None if any(n is None for n in numbers) else numbers


def typed(parameter: Parameter) -> Parameter:
    """``parameter`` as the double (or double array) its parameter is, where it was given as a
    number of another type: an integer, or a string that reads as a number.

    rclpy's ``parameter_dict_from_yaml_file`` (``ros2 param load``) reads a file's value, turns
    it into text with ``str()`` and reads that again as YAML 1.1: ``2.0e-05`` in a file becomes
    the float 2e-05, then the text ``'2e-05'``, which YAML 1.1 reads as a string. No way of
    writing the file avoids it for a double below 1e-4 or from 1e16 up, so such a string (and
    a list mixing integers and floats, which arrives as one string) is taken as its number here.
    """
    if parameter.name not in NAMES and parameter.name not in NODE_PARAMETERS:
        return parameter
    kind = _kind(parameter.name)
    value = parameter.value
    if kind == "float" and parameter.type_ in (Parameter.Type.INTEGER, Parameter.Type.STRING):
        number = _number(value)
        return parameter if number is None else Parameter(parameter.name, Parameter.Type.DOUBLE, number)
    if kind == "list" and parameter.type_ in (Parameter.Type.DOUBLE, Parameter.Type.INTEGER):
        return Parameter(parameter.name, Parameter.Type.DOUBLE_ARRAY, [float(value)])
    if kind == "list" and parameter.type_ in (
        Parameter.Type.INTEGER_ARRAY,
        Parameter.Type.STRING_ARRAY,
        Parameter.Type.STRING,
    ):
        numbers = _numbers(value)
        return parameter if numbers is None else Parameter(parameter.name, Parameter.Type.DOUBLE_ARRAY, numbers)
    return parameter


def check_known(names: Iterable[str] | Mapping[str, Parameter], argv: Sequence[str] | None = None) -> None:
    """Raise ConfigError for a key that is none of this node's parameters, naming the closest.

    Given the overrides rclpy read (name -> Parameter), also refuse a ``-p`` value that rcl
    does not use (see :func:`check_overrides`); ``argv`` is the command line rclpy read,
    ``sys.argv`` by default (what ``rclpy.init()`` reads without ``args``).
    """
    known = (*all_names(), *SCENARIO)  # a params file may set the scenario, for the CLI
    for name in names:
        if name in known or name in _STANDARD or name.startswith(_STANDARD_PREFIXES):
            continue
        close = difflib.get_close_matches(name, known, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(f"unknown parameter '{name}' for boom_sim{hint} (boom_sim --help lists them)")
    if isinstance(names, Mapping):
        check_overrides(names, sys.argv if argv is None else argv)


def assignments(args: Sequence[str], node_name: str = "boom_sim") -> list[tuple[int, str, str]]:
    """The ``-p NAME:=VALUE`` (``--param``) in the ROS arguments of ``args`` that are for this node:
    (position, NAME, VALUE as written). ``-p node:NAME:=VALUE`` counts where node is this node or ``**``."""
    found, in_ros = [], False
    for i, arg in enumerate(args):
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif in_ros and arg in ("-p", "--param") and i + 1 < len(args):
            key, sep, text = args[i + 1].partition(":=")
            node, _, name = key.rpartition(":")
            if sep and (not node or node.rsplit("/", 1)[-1] in (node_name, "**", "*")):
                found.append((i, name, text))
    return found


def on_command_line(message: str, args: Sequence[str]) -> str:
    """A start-up refusal ``message`` that names a parameter ('NAME') given by ``-p`` in ``args``,
    led by that ``-p NAME:=VALUE`` (the last one), so that it points at what the user typed,
    not at a params file that may not have been given."""
    last = {name: text for _, name, text in assignments(args)}
    for name, text in last.items():
        if f"'{name}'" in message and not message.startswith("-p "):
            return f"-p {name}:={text}: {message}"
    return message


def _file_names(path: str) -> set[str]:
    """Every parameter name a params file sets, for any node (empty if it cannot be read)."""
    try:
        document = config.read_document(path)
    except ConfigError:
        return set()
    names: set[str] = set()
    for section in document.values() if isinstance(document, Mapping) else ():
        if isinstance(section, Mapping) and isinstance(section.get("ros__parameters"), Mapping):
            names.update(config.flatten(section["ros__parameters"]))
    return names


def _rcl_key(value: Any) -> Any:
    """A value with its type, as rcl tells types apart (an int 50 is not the double 50.0); a NaN
    is its text, so that it equals itself (``-p x:=.nan`` is the NaN rcl keeps)."""
    value = plain(value)
    if isinstance(value, list):
        return ("list", tuple(_rcl_key(v) for v in value))
    if isinstance(value, float) and math.isnan(value):
        return ("float", "nan")
    return (type(value).__name__, value)


def _expected(name: str) -> str:
    kind = _kind(name) if name in NAMES or name in NODE_PARAMETERS else "bool" if name == "use_sim_time" else ""
    return {
        "float": "a number",
        "int": "an integer",
        "bool": "true or false",
        "str": "text",
        "list": "a list of numbers",
    }.get(kind, "one value")


def check_overrides(overrides: Mapping[str, Parameter], argv: Sequence[str]) -> None:
    """Raise ConfigError where the last ``-p`` of a parameter on the command line is not the value
    rcl hands the node.

    rcl keeps one value per type of each parameter, and hands over the one of the first type of
    bool, integer, double, string, then the arrays: ``-p payload_mass_kg:=50.0 -p payload_mass_kg:=abc``
    (or ``abc`` after a params file's 50.0) runs with 50.0, silently. Of values of one type the last
    wins, as ROS documents: ``-p x:=1.0 -p x:=2.0`` is 2.0 and passes. A params file given after
    the last ``-p`` of a name has the last word on it: that name is not checked.
    """
    given = assignments(argv)
    files = _params_file_args(argv)
    last: dict[str, tuple[int, str]] = {}
    for position, name, text in given:
        last[name] = (position, text)
    for name, (position, text) in last.items():
        if name not in overrides or any(i > position and name in _file_names(path) for i, path in files):
            continue
        try:
            meant = config.load_yaml(text) if text.strip() else text
        except yaml.YAMLError:
            meant = text
        kept = overrides[name].value
        if _rcl_key(kept) != _rcl_key(meant):
            times = sum(1 for _, n, _ in given if n == name)
            where = f"it is given {times} times, and" if times > 1 else "a params file gives it before, and"
            raise ConfigError(
                f"-p {name}:={text} would not be used: {where} rcl keeps {plain(kept)!r}, an earlier value "
                f"of another type; give {name} once, as {_expected(name)}"
            )


#: The finest time step the node takes, s: it steps in real time, and a step of 1e-20 s made
#: counts of steps per tick and per run beyond what a 64-bit integer holds (an OverflowError
#: that stopped the simulation, or a traceback at start). boom-sim takes finer ones for a run.
NODE_MIN_TIME_STEP_S = 1e-9


def check_node_model(params: Any) -> None:
    """Raise ConfigError for model parameters the node cannot step (``params``: Parameters)."""
    if params.time_step_s < NODE_MIN_TIME_STEP_S:
        raise ConfigError(
            f"parameter 'time_step_s' is {params.time_step_s:g} s; boom_sim steps in real time and takes a step of "
            f"at least {NODE_MIN_TIME_STEP_S:g} s ({1 / params.time_step_s:.3g} steps per simulated second could not "
            "be counted); boom-sim run takes finer ones"
        )


def undeclared(name: str) -> str | None:
    """Why the running node refuses to set ``name``, naming the closest parameter it has (None
    for a parameter it declares). rclpy's own reason, 'Invalid access to undeclared parameter(s):
    []', names neither."""
    if name in all_names() or name in _STANDARD or name.startswith(_STANDARD_PREFIXES):
        return None
    close = difflib.get_close_matches(name, all_names(), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    if name in SCENARIO:
        return (
            f"boom_sim has no parameter '{name}': the command_* parameters are boom-sim's headless scenario, and the "
            f"node takes its commands from topics{hint}"
        )
    return f"boom_sim has no parameter '{name}'{hint} (boom_sim --help lists them)"


def check_node_parameter(name: str, value: Any) -> None:
    """Raise ConfigError unless ``value`` fits node parameter ``name``."""
    value_default, _, _, low, high = NODE_PARAMETERS[name]
    if isinstance(value_default, str):
        if not isinstance(value, str) or not value:
            raise ConfigError(f"parameter '{name}' must be a non-empty string, got {value!r}")
    elif isinstance(value_default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"parameter '{name}' must be true or false, got {value!r}")
    elif isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise ConfigError(f"parameter '{name}' must be a number in [{low}, {high}], got {value!r}")


def user_args(args: Sequence[str]) -> list[str]:
    """``args`` without the ``--ros-args ... [--]`` sections (what rclpy's parser would remove)."""
    kept, in_ros = [], False
    for arg in args:
        if arg == "--ros-args":
            in_ros = True
        elif in_ros and arg == "--":
            in_ros = False
        elif not in_ros:
            kept.append(arg)
    return kept


def params_files(args: Sequence[str]) -> list[str]:
    """The files named by ``--params-file`` in the ROS arguments of ``args``."""
    return [path for _, path in _params_file_args(args)]


def _params_file_args(args: Sequence[str]) -> list[tuple[int, str]]:
    """(position, file) of each ``--params-file`` in the ROS arguments of ``args``: one after
    ``--`` is the program's own argument, which rcl does not read."""
    files, in_ros = [], False
    for i, arg in enumerate(args):
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif in_ros and arg == "--params-file" and i + 1 < len(args):
            files.append((i, args[i + 1]))
    return files


def check_params_file(path: str) -> None:
    """Raise ConfigError, in one line, if ``path`` is missing or not a params YAML mapping."""
    try:
        document = config.read_document(path)
    except ConfigError as exc:
        raise ConfigError(f"--params-file {exc}") from None
    if not isinstance(document, dict) or not all(
        isinstance(v, dict) and isinstance(v.get("ros__parameters"), dict) for v in document.values()
    ):
        raise ConfigError(f"--params-file {path}: expected '/**: ros__parameters: {{name: value, ...}}' per node")


def usage() -> str:
    """``boom_sim --help``: how to start it, and every parameter with its default and unit."""
    lines = [
        "usage: boom_sim [--ros-args [--params-file FILE] [-p NAME:=VALUE] [-r __ns:=/NAMESPACE] ...]",
        "",
        "ROS 2 node simulating the hydraulic drive of a crane boom. Subscribes to valve_command",
        "(boom_hydraulics_msgs/ValveCommand), commands (std_msgs/Float64MultiArray),",
        "~/joint_trajectory (trajectory_msgs/JointTrajectory, boom_joint) and joint_commands",
        "(sensor_msgs/JointState: boom_joint's position and velocity, as ros2_control's JointState",
        "topic hardware interface sends them); serves the action ~/move_boom",
        "(boom_hydraulics_msgs/MoveBoom); publishes drive_state, joint_states, piston_pressure,",
        "rod_pressure, rod_force, hinge_wrench, robot_description, ~/markers and /diagnostics.",
        "With use_sim_time:=true (rclpy's standard parameter) it follows /clock.",
        "",
        "Node parameters (* = at start only; read_only once running):",
    ]
    node_width = max(map(len, NODE_PARAMETERS))
    for name, (value, unit, text, _, _) in NODE_PARAMETERS.items():
        star = "*" if name in START_ONLY else " "
        lines.append(f"  {star} {name:<{node_width}} {value!s:<10} {unit:<5} {text}")
    lines += ["", "Model parameters (config/default.yaml lists them; ros2 param describe gives ranges):"]
    width = max(map(len, MODEL_NAMES))
    defaults = {name: str(describe(name)["default"]) for name in MODEL_NAMES}
    value_width = max(map(len, defaults.values()))
    for name in MODEL_NAMES:
        lines.append(f"    {name:<{width}} {defaults[name]:<{value_width}} {describe(name)['unit']}")
    lines += [
        "",
        "A params file may also set the command_* parameters of boom-sim's headless scenario;",
        "the node takes its valve commands from topics and ignores them.",
    ]
    return "\n".join(lines)


#: The group of the node's own parameters in :func:`markdown_reference`.
NODE_GROUP = "node"


def _range_text(name: str) -> str:
    """The allowed values of parameter ``name``: ``(0, 20]``, ``[1, 10000]``, ``one of: a, b``, or ''."""
    if name in NODE_PARAMETERS:
        _, _, _, low, high = NODE_PARAMETERS[name]
        return "" if low is None or high is None else f"[{low:g}, {high:g}]"
    meta = describe(name)
    if meta["choices"]:
        return "one of: " + ", ".join(meta["choices"])
    low, high = meta["low"], meta["high"]
    if low is None or high is None:
        return ""
    return f"{'[' if meta['low_inclusive'] else '('}{low:g}, {high:g}]"


def _cell(text: str) -> str:
    """``text`` for a Markdown table cell: a '|' would end the cell."""
    return text.replace("|", "\\|")


def markdown_reference() -> str:
    """The parameter reference as a Markdown table, generated from the schema (docs/ros-api.md
    holds it; a test keeps the two equal): every parameter, by group (plant, solver, controller,
    the node's own, then the scenario, which only the headless tools read), with its type,
    default as a params file writes it, unit, range, whether it applies at start only, and
    its description."""
    order = [name for group in GROUPS if group != "scenario" for name in names_in(group) if name in MODEL_NAMES]
    order += list(NODE_PARAMETERS) + list(SCENARIO)
    lines = [
        "| Name | Group | Type | Default | Unit | Range | Start only | Description |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name in order:
        if name in NODE_PARAMETERS:
            group, unit, text = NODE_GROUP, NODE_PARAMETERS[name][1], NODE_PARAMETERS[name][2]
        else:
            meta = describe(name)
            group, unit, text = group_of(name), meta["unit"], meta["description"]
        cells = (
            f"`{name}`",
            group,
            _kind(name),
            f"`{config.scalar_text(default(name))}`",
            unit,
            _range_text(name),
            "yes" if name in START_ONLY else "",
            text,
        )
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"
