"""The arguments of ``boom_sim.launch.py`` and what they start, without the launch library.

The launch file declares :data:`ARGUMENTS` and asks :func:`plan` what to start, so that
the arguments are tested on machines without ``ros2 launch`` too.

Recording: a robot stack that launches the node must not find a ``bags/`` folder in its
working directory, so the launch file records only with ``record:=true``, into
``$ROS_HOME/boom_hydraulics/bags`` (``~/.ros/...`` by default). ``make run`` (boom-demo)
and a bare ``boom_sim`` record into ``bags/`` as before.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError
from .node_parameters import check_params_file


def ros_home() -> str:
    """$ROS_HOME, or ~/.ros as ROS 2 takes it."""
    return os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")


def default_record_folder() -> str:
    return os.path.join(ros_home(), "boom_hydraulics", "bags")


@dataclass(frozen=True)
class Argument:
    name: str
    default: Callable[[], str]
    description: str


#: name, default, description: what ``ros2 launch boom_hydraulics boom_sim.launch.py --show-args`` lists.
ARGUMENTS: tuple[Argument, ...] = (
    Argument("namespace", lambda: "", "ROS namespace of boom_sim (and robot_state_publisher), e.g. crane1"),
    Argument("use_sim_time", lambda: "false", "true: follow /clock published by another node (a simulator)"),
    Argument("params_file", lambda: "", "ROS 2 params YAML for boom_sim (empty: the package's config/default.yaml)"),
    Argument("record", lambda: "false", "true: record the run to an MCAP bag"),
    Argument("record_folder", default_record_folder, "folder in which each run's bag folder is created"),
    Argument(
        "robot_state_publisher",
        lambda: "auto",
        "start robot_state_publisher for TF: auto (when it is installed), true or false",
    ),
    Argument("rviz", lambda: "false", "true: start RViz with the package's rviz/boom_crane.rviz"),
)
NAMES = tuple(a.name for a in ARGUMENTS)


def _flag(name: str, value: str) -> bool:
    text = value.strip().lower()
    if text in ("true", "1", "yes"):
        return True
    if text in ("false", "0", "no"):
        return False
    raise ConfigError(f"launch argument {name}:={value!r}: expected true or false")


@dataclass(frozen=True)
class Plan:
    """What the launch file starts."""

    namespace: str
    params_file: str
    sim_parameters: dict[str, Any]  # boom_sim's parameters beside the params file (they win)
    state_publisher: bool
    rviz: bool


def plan(
    values: Mapping[str, str],
    default_params_file: str,
    state_publisher_installed: bool,
    rviz_installed: bool = False,
) -> Plan:
    """The nodes and their parameters for the launch arguments ``values`` (strings, as given).

    Raises ConfigError before anything starts for a node asked for that is not installed: a
    launch that fails to find an executable once boom_sim runs exits and leaves boom_sim running;
    and for a ``params_file`` that is missing or not a params file, which launch_ros only warns
    about (the node then ran on its defaults), where ``ros2 run`` refuses it (exit 2).
    """
    unknown = set(values) - set(NAMES)
    if unknown:
        raise ConfigError(f"unknown launch arguments {sorted(unknown)}; choose from {', '.join(NAMES)}")
    v = {a.name: values.get(a.name, a.default()) for a in ARGUMENTS}
    rsp = v["robot_state_publisher"].strip().lower()
    if rsp not in ("auto", "true", "false"):
        raise ConfigError(f"launch argument robot_state_publisher:={rsp!r}: expected auto, true or false")
    if rsp == "true" and not state_publisher_installed:
        raise ConfigError("robot_state_publisher:=true, but robot_state_publisher is not installed")
    state_publisher = rsp == "true" or (rsp == "auto" and state_publisher_installed)
    sim_time = _flag("use_sim_time", v["use_sim_time"])
    rviz = _flag("rviz", v["rviz"])
    if rviz and not rviz_installed:
        raise ConfigError("rviz:=true, but rviz2 is not installed; install rviz2 or leave rviz:=false")
    if v["params_file"]:
        try:
            check_params_file(v["params_file"])
        except ConfigError as exc:
            raise ConfigError(f"launch argument params_file: {str(exc).removeprefix('--params-file ')}") from None
    return Plan(
        namespace=v["namespace"].strip("/"),
        params_file=v["params_file"] or default_params_file,
        sim_parameters={
            "use_sim_time": sim_time,
            "record": _flag("record", v["record"]),
            "record_folder": v["record_folder"] or default_record_folder(),
            # one publisher of robot_description: robot_state_publisher when it runs
            "publish_robot_description": not state_publisher,
        },
        state_publisher=state_publisher,
        rviz=rviz,
    )
