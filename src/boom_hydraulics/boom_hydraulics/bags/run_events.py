"""The node's run events: what it did to its own time line, recorded so that a run can be
simulated again whole (boom-resim).

The node publishes each event on ``~/events`` as a ``std_msgs/String`` holding one JSON
object, and records it in its bag like every topic it publishes; its run description names
the topic (``events_topic``), which says that every event of the run is in the bag. An event:

- ``event``: ``reset`` (``~/reset``, or a ROS clock that jumped back), ``pause``, ``resume``,
  ``step`` (a ``~/step`` call), ``backlog_dropped`` (the node fell behind real time by more
  than ``max_catch_up_s`` and gave up the rest) or ``pace`` (a new ``real_time_factor``);
- ``sim_time_s``: the simulated time it took effect at (a float, written as Python's repr,
  which reads back to the same bits);
- ``states_before``: how many DriveState messages the node had published (and recorded)
  before it: the states from this index on come after the event;
- ``clock_origin_ns``: the time origin after it, the node-clock time of simulated time 0
  (state stamps are ``clock_origin_ns`` plus simulated time; ROS-time command stamps map
  back through it), and ``origin_moved_ns``, how far the event moved it;
- for a reset: ``cause``, ``rod_position_m`` (null: the start length), ``stopped`` (the
  simulation had stopped on a failure, and stood still, before it) and ``state``, the state
  vector after it; for a step: ``steps``; for a dropped backlog: ``dropped_s``; for a new
  pace: ``real_time_factor``.

A JSON string, not a message type of its own: every bag reader (rosbag2, rosbags, mcap,
Foxglove) shows it without this workspace's messages, and a field can be added without
breaking a reader; :func:`parse` checks every field it reads.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

#: The message type of ``~/events``.
EVENTS_TYPE = "std_msgs/msg/String"
KINDS = ("reset", "pause", "resume", "step", "backlog_dropped", "pace")


@dataclass(frozen=True)
class RunEvent:
    """One event of a run (see the module docstring)."""

    event: str
    sim_time_s: float
    states_before: int
    clock_origin_ns: int
    origin_moved_ns: int = 0
    cause: str | None = None  # reset
    rod_position_m: float | None = None  # reset: where it put the rod (None: the start length)
    stopped: bool = False  # reset: the simulation had stopped on a failure before it
    state: list[float] = field(default_factory=list)  # reset: the state after it
    steps: int = 0  # step
    dropped_s: float = 0.0  # backlog_dropped
    real_time_factor: float = 1.0  # pace: the new one

    def to_json(self) -> str:
        """The event as the node publishes it: only the fields of its kind."""
        keep = {"event", "sim_time_s", "states_before", "clock_origin_ns", "origin_moved_ns"}
        keep |= {"reset": {"cause", "rod_position_m", "stopped", "state"}, "step": {"steps"}}.get(self.event, set())
        keep |= {"dropped_s"} if self.event == "backlog_dropped" else set()
        keep |= {"real_time_factor"} if self.event == "pace" else set()
        return json.dumps({k: v for k, v in asdict(self).items() if k in keep}, allow_nan=False)


def _number(record: dict, name: str, kind: type, optional: bool = False) -> Any:
    value = record.get(name)
    if value is None and optional:
        return None
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or isinstance(value, bool) != (kind is bool):
        raise ValueError(f"'{name}' is {value!r}, not a{'n' if kind is int else ''} {kind.__name__}")
    if kind is float and not math.isfinite(value):
        raise ValueError(f"'{name}' is {value!r}, not a finite number")
    return value


def parse(text: str) -> RunEvent:
    """The event in one ``~/events`` message; ValueError naming what does not read."""
    try:
        record = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ValueError(f"not JSON ({exc})") from None
    if not isinstance(record, dict) or record.get("event") not in KINDS:
        raise ValueError(f"no event of {', '.join(KINDS)} in {text[:80]!r}")
    kind = record["event"]
    state = record.get("state", [])
    if not isinstance(state, list) or not all(isinstance(x, (int, float)) for x in state):
        raise ValueError(f"'state' is {state!r}, not a list of numbers")
    return RunEvent(
        event=kind,
        sim_time_s=_number(record, "sim_time_s", float),
        states_before=_number(record, "states_before", int),
        clock_origin_ns=_number(record, "clock_origin_ns", int),
        origin_moved_ns=_number(record, "origin_moved_ns", int),
        cause=record.get("cause") if kind == "reset" else None,
        rod_position_m=_number(record, "rod_position_m", float, optional=True) if kind == "reset" else None,
        stopped=_number(record, "stopped", bool) if kind == "reset" else False,
        state=[float(x) for x in state],
        steps=_number(record, "steps", int) if kind == "step" else 0,
        dropped_s=_number(record, "dropped_s", float) if kind == "backlog_dropped" else 0.0,
        real_time_factor=_number(record, "real_time_factor", float) if kind == "pace" else 1.0,
    )


def origin_at(events: Sequence[RunEvent], first_origin_ns: int, state_index: int) -> int:
    """The time origin of the state at ``state_index`` (log order): that of the last event
    before it, or the run's first."""
    origin = first_origin_ns
    for event in events:
        if event.states_before > state_index:
            break
        origin = event.clock_origin_ns
    return origin
