"""A boom_sim bag read as a run to simulate again: its description, the valve commands and
parameter changes with the instants they act at, the setpoints of the position controller and
the paths it followed (with where the node took each), the published state instants, the
node's run events (resets, pauses, steps, dropped backlogs: bags.run_events) and its own
counts of them."""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader, AnyReaderError

from ..bags.encoding import DRIVE_STATE, ENERGY_LEDGER, SETPOINT_PATH, RecordedPath, recorded_path
from ..bags.recording import Topic, offered_qos
from ..bags.run_description import RunDescription
from ..bags.run_events import RunEvent, origin_at, parse
from ..errors import BagError

VALVE_COMMAND = "boom_hydraulics_msgs/msg/ValveCommand"
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
#: The node's diagnostics status that counts resets, pauses and steps, and how far its origin moved.
RUN_STATUS = "boom_sim: run"
_RUN_KEYS = ("resets", "pauses", "step_calls", "clock_origin_shift_s")
JOINT_STATE = "sensor_msgs/msg/JointState"
ARRAY_COMMAND = "std_msgs/msg/Float64MultiArray"
PARAMETER_EVENT = "rcl_interfaces/msg/ParameterEvent"
#: ParameterValue.type -> the field that holds the value (rcl_interfaces/msg/ParameterType)
_VALUE_FIELDS = {
    1: "bool_value",
    2: "integer_value",
    3: "double_value",
    4: "string_value",
    5: "byte_array_value",
    6: "bool_array_value",
    7: "integer_array_value",
    8: "double_array_value",
    9: "string_array_value",
}


@dataclass
class Recorded:
    """One recorded message to copy into the new bag: when it acts, when it was logged."""

    at_ns: int  # on the node's clock: when it takes effect
    log_ns: int
    topic: str
    raw: bytes
    opening: float = math.nan  # commands
    changes: dict[str, Any] = field(default_factory=dict)  # parameter events
    stamp_ns: int = 0  # a ValveCommand's header stamp (0: unset)
    # commands: the node's simulated instant (a stamp on its clock) when it took the command,
    # known from the drive states logged before it; None in a bag without them
    taken_ns: int | None = None
    taken_after: int = 0  # commands: how many drive states the node had published when it took it
    origin_ns: int = 0  # the node's time origin when it logged the message (its stamps map through it)


@dataclass
class TakenPath:
    """A setpoint path the node's controller started to follow (~/setpoint_path), with when the
    node took it: after ``taken_after`` drive states, logged at ``log_ns`` (as a command)."""

    path: RecordedPath
    log_ns: int
    taken_after: int
    topic: str
    raw: bytes


@dataclass
class RecordedRun:
    """What a node recorded about its run, enough to run it again."""

    description: RunDescription  # the parameters, time origin, publish rate, command timeout, node
    end_ns: int
    state_topic: str
    # the instants the node published DriveState at (their stamps): in the order it published
    # them where the bag holds its run events, else by stamp
    state_ns: list[int]
    state_log_ns: list[int]  # when it published each (its log time), in the order of state_ns
    topics: list[Topic]  # of the commands and parameter events, with their recorded offers
    commands: list[Recorded]
    parameter_changes: list[Recorded]
    setpoints: list[tuple[int, float, float]] = field(default_factory=list)  # (stamp ns, rad, rad/s)
    # the node's own count of what breaks the time line (its "boom_sim: run" diagnostics), the latest
    run_counts: dict[str, float] = field(default_factory=dict)
    # the recorded drive states' q1, v, a and valve loss energy, in stamp order (reset detection)
    state_signals: tuple[list[float], ...] = ((), (), (), ())
    energy_topic: str | None = None  # where the node published its energy ledger (None: it did not)
    # the node's run events in the order it recorded them, and each as recorded (log ns, raw)
    # (none where the bag has no events_topic: recorded before the node recorded them)
    events: list[RunEvent] = field(default_factory=list)
    event_messages: list[tuple[int, bytes]] = field(default_factory=list)
    # each path the controller started to follow, in the order taken (none in a bag from before
    # the node recorded them, or without drive states to place them)
    paths: list[TakenPath] = field(default_factory=list)
    setpoint_topic: str | None = None  # where the node published its controller's setpoint (None: nowhere)

    @property
    def has_events(self) -> bool:
        """Whether the bag holds every run event of its node (its description names their topic)."""
        return self.description.events_topic is not None

    def state_origin_ns(self, index: int) -> int:
        """The time origin the state at ``index`` (of :attr:`state_ns`) was stamped with."""
        return origin_at(self.events, self.clock_origin_ns, index)

    def state_origins_ns(self) -> list[int]:
        """The time origin of each state of :attr:`state_ns`, in one pass."""
        origins, origin, k = [], self.clock_origin_ns, 0
        for index in range(len(self.state_ns)):
            while k < len(self.events) and self.events[k].states_before <= index:
                origin = self.events[k].clock_origin_ns
                k += 1
            origins.append(origin)
        return origins

    def state_sim_s(self, index: int) -> float:
        """The simulated time of the state at ``index``."""
        return (self.state_ns[index] - self.state_origin_ns(index)) * 1e-9

    @property
    def parameters(self) -> dict[str, Any]:
        return self.description.parameters

    @property
    def clock_origin_ns(self) -> int:
        return self.description.clock_origin_ns

    @property
    def publish_rate_hz(self) -> float:
        return self.description.publish_rate_hz

    @property
    def command_timeout_s(self) -> float:
        return self.description.command_timeout_s

    @property
    def node(self) -> str | None:
        """The recording node's fully qualified name, where recorded."""
        return self.description.node


#: The DriveState fields the reset detection reads (refusals.break_in_states).
_CONTINUITY_FIELDS = ("rod_position_m", "rod_velocity_m_s", "rod_acceleration_m_s2", "valve_loss_energy_j")


def _stamp_ns(msg: Any) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _messages(reader: AnyReader, connections: Sequence[Any]):
    """The messages of ``connections``, deserialised; none for no connections (rosbags reads an
    empty list as every connection)."""
    if not connections:
        return
    for connection, log_ns, raw in reader.messages(connections=connections):
        yield connection, log_ns, raw, reader.deserialize(raw, connection.msgtype)


class NodeInstants:
    """The node's simulated instant (as a stamp on its clock) when it took a message logged at
    some time. The node takes commands between ticks, and each tick ends with the DriveState of
    its last step: the instant is that of the last state logged before the message (the time
    origin before the first). On the node's own clock it equals the message's log time while
    the node keeps up; when it falls behind (a loaded machine, a stall it catches up on), only
    this says when a command that was unstamped or already passed took effect. A state and a
    message logged at the same time: with publish_clock (log times are simulated time) the
    tick came first, so the state counts; on a shared clock (use_sim_time) the node now logs
    what it handles at one clock reading 1 ns apart, in order, so there are no such ties; in
    its bags from before, the clock had not moved since the tick before, so the state does not
    count."""

    def __init__(self, origin_ns: int, logged: Sequence[tuple[int, int]]) -> None:
        self.origin_ns = origin_ns
        self.log_ns = [log for log, _ in logged]  # never decreasing: one channel's log times
        self.stamp_ns = [stamp for _, stamp in logged]
        self._after = bisect.bisect_right if origin_ns == 0 else bisect.bisect_left  # origin 0: publish_clock

    def at(self, log_ns: int) -> int:
        k = self._after(self.log_ns, log_ns)
        return self.stamp_ns[k - 1] if k else self.origin_ns

    def count(self, log_ns: int) -> int:
        """How many states the node had published when it took a message logged at ``log_ns``."""
        return self._after(self.log_ns, log_ns)


def _origins(description: RunDescription, events: Sequence[tuple[int, RunEvent]]):
    """The node's time origin at a log time: that of the last event logged at or before it."""
    log_times = [log for log, _ in events]
    origins = [event.clock_origin_ns for _, event in events]

    def at(log_ns: int) -> int:
        k = bisect.bisect_right(log_times, log_ns)
        return origins[k - 1] if k else description.clock_origin_ns

    return at


def _parameter_value(value: Any) -> Any:
    field_name = _VALUE_FIELDS.get(value.type)
    if field_name is None:
        return None
    raw = getattr(value, field_name)
    return [v.item() if hasattr(v, "item") else v for v in raw] if field_name.endswith("array_value") else raw


def _run_values(values: Sequence[Any]) -> dict[str, float]:
    """The counts of a "boom_sim: run" status (KeyValue text), those that read as numbers."""
    out = {}
    for kv in values:
        if kv.key in _RUN_KEYS:
            try:
                out[kv.key] = float(kv.value)
            except ValueError:
                continue
    return out


def read_run(bag: Path, description: RunDescription) -> RecordedRun:
    """The valve commands, parameter changes, setpoints and states a boom_sim node recorded in
    ``bag``, whose run description (bags.reading.read_run_description) is ``description``."""
    node_name = description.node
    try:
        with AnyReader([bag]) as reader:
            states = [c for c in reader.connections if c.msgtype == DRIVE_STATE]
            energy_topic = next((c.topic for c in reader.connections if c.msgtype == ENERGY_LEDGER), None)
            logged_states = [
                (log_ns, _stamp_ns(msg), *(float(getattr(msg, name)) for name in _CONTINUITY_FIELDS))
                for _, log_ns, _, msg in _messages(reader, states[:1])
            ]
            # with the run's events, in the order published (a reset at an instant publishes it
            # again; a ROS clock that jumped back stamps later states earlier)
            has_events = description.events_topic is not None
            recorded_states = logged_states if has_events else sorted(logged_states, key=lambda row: row[1])
            events = _events(bag, reader, description.events_topic) if has_events else []
            origin_of = _origins(description, [(log, event) for log, _, event in events])
            node_instants = NodeInstants(description.clock_origin_ns, [row[:2] for row in logged_states])
            wanted = [c for c in reader.connections if c.msgtype in (VALVE_COMMAND, ARRAY_COMMAND, PARAMETER_EVENT)]
            topics = [
                Topic(c.topic, c.msgtype, tuple(getattr(c.ext, "offered_qos_profiles", ())) or (offered_qos(),))
                for c in wanted
            ]
            setpoint_topics = [
                c for c in reader.connections if c.msgtype == JOINT_STATE and c.topic.endswith("/setpoint")
            ]
            setpoints = sorted(
                (_stamp_ns(msg), msg.position[0], msg.velocity[0])
                for _, _, _, msg in _messages(reader, setpoint_topics[:1])
            )
            path_connections = [
                c for c in reader.connections if c.msgtype == SETPOINT_PATH and c.topic.endswith("/setpoint_path")
            ][:1]
            paths = [
                TakenPath(recorded_path(msg), log_ns, node_instants.count(log_ns), connection.topic, bytes(raw))
                for connection, log_ns, raw, msg in _messages(reader, path_connections if logged_states else [])
            ]
            topics += [
                Topic(c.topic, c.msgtype, tuple(getattr(c.ext, "offered_qos_profiles", ())) or (offered_qos(),))
                for c in path_connections
                if paths
            ]
            run_counts: dict[str, float] = {}
            diagnostics = [c for c in reader.connections if c.msgtype == DIAGNOSTICS]
            for _, _, _, msg in _messages(reader, diagnostics):
                for status in msg.status:
                    if status.name == RUN_STATUS:
                        run_counts.update(_run_values(status.values))
            commands, changes = [], []
            for connection, log_ns, raw, msg in _messages(reader, wanted):
                if connection.msgtype == PARAMETER_EVENT:
                    if node_name and msg.node != node_name:
                        continue
                    values = {p.name: _parameter_value(p.value) for p in msg.changed_parameters}
                    at_ns = msg.stamp.sec * 1_000_000_000 + msg.stamp.nanosec
                    changes.append(
                        Recorded(
                            at_ns, log_ns, connection.topic, bytes(raw), changes=values, origin_ns=origin_of(log_ns)
                        )
                    )
                    continue
                # the node's rule: at its stamp, or at the node's instant when it took the command
                # if unstamped or already passed (without drive states: when it was logged)
                taken_ns = node_instants.at(log_ns) if logged_states else None
                if connection.msgtype == VALVE_COMMAND:
                    stamp_ns, opening = _stamp_ns(msg), msg.opening
                else:
                    stamp_ns, opening = 0, (msg.data[0] if len(msg.data) == 1 else math.nan)
                at_ns = max(stamp_ns, log_ns if taken_ns is None else taken_ns)
                commands.append(
                    Recorded(
                        at_ns,
                        log_ns,
                        connection.topic,
                        bytes(raw),
                        float(opening),
                        stamp_ns=stamp_ns,
                        taken_ns=taken_ns,
                        taken_after=node_instants.count(log_ns),
                        origin_ns=origin_of(log_ns),
                    )
                )
            end_ns = reader.end_time
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (ValueError, KeyError, IndexError, AttributeError) as exc:  # a message of another layout than its type
        raise BagError(
            f"{bag}: a message does not fit its recorded type ({exc!r}); was it recorded by boom_sim?"
        ) from None
    return RecordedRun(
        description=description,
        end_ns=end_ns,
        state_topic=states[0].topic if states else "/drive_state",
        state_ns=[row[1] for row in recorded_states],
        state_log_ns=[row[0] for row in recorded_states],
        topics=topics,
        commands=commands,
        parameter_changes=sorted(changes, key=lambda r: r.at_ns),
        setpoints=setpoints,
        run_counts=run_counts,
        state_signals=tuple(list(column) for column in zip(*recorded_states))[2:] or ((), (), (), ()),
        energy_topic=energy_topic or (f"{node_name}/energy" if node_name else None),
        events=[event for _, _, event in events],
        event_messages=[(log, raw) for log, raw, _ in events],
        paths=paths,
        setpoint_topic=setpoint_topics[0].topic if setpoint_topics else None,
    )


def _events(bag: Path, reader: AnyReader, topic: str) -> list[tuple[int, bytes, RunEvent]]:
    """The run events recorded on ``topic``: (log ns, raw, event), in the order recorded.
    Raises BagError for one that does not read (the bag is not whole)."""
    connections = [c for c in reader.connections if c.topic == topic]
    out = []
    for _, log_ns, raw, msg in _messages(reader, connections):
        try:
            event = parse(msg.data)
        except ValueError as exc:
            raise BagError(f"{bag}: a run event on {topic} does not read ({exc}); the bag is not whole") from None
        out.append((log_ns, bytes(raw), event))
    return out
