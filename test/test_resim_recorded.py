"""A recorded run read back for boom-resim (resim.recorded.read_run), on small bags made here:
when each command and parameter change acts, the states in the order the node published them,
the setpoints and the paths the controller followed, the node's own counts and run events, and
the time origin of each."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy")
from action_msgs.msg import GoalStatusArray
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, Header, String

from boom_hydraulics.bags import cdr
from boom_hydraulics.bags.encoding import (
    DRIVE_STATE,
    ENERGY_LEDGER,
    SETPOINT_PATH,
    START_BOOM,
    START_OWN,
    START_SETPOINT,
    RecordedPath,
    message,
    parameter_event_cdr,
    setpoint_path_cdr,
    to_cdr,
    typestore,
)
from boom_hydraulics.bags.recording import BagRecorder, Topic, offered_qos
from boom_hydraulics.bags.run_description import RunDescription
from boom_hydraulics.bags.run_events import RunEvent
from boom_hydraulics.errors import BagError
from boom_hydraulics.model.setpoints import SetpointPath, knot_offsets_ns, move, on_whole_ns, path_from_offsets
from boom_hydraulics.resim.recorded import (
    ARRAY_COMMAND,
    DIAGNOSTICS,
    JOINT_STATE,
    PARAMETER_EVENT,
    VALVE_COMMAND,
    NodeInstants,
    Recorded,
    read_run,
)
from boom_hydraulics_msgs.msg import DriveState, EnergyLedger, ValveCommand

ORIGIN = 3_000_123  # the node-clock time of simulated time 0, ns (a shared clock that had run 3 ms)
MS = 1_000_000
NODE = "/crane/boom_sim"


def _time(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _state(stamp_ns: int, q: float = 0.0, v: float = 0.0, a: float = 0.0, e: float = 0.0) -> DriveState:
    return DriveState(
        header=Header(stamp=_time(stamp_ns)),
        rod_position_m=q,
        rod_velocity_m_s=v,
        rod_acceleration_m_s2=a,
        valve_loss_energy_j=e,
    )


def _command(stamp_ns: int, opening: float) -> ValveCommand:
    return ValveCommand(header=Header(stamp=_time(stamp_ns)), opening=opening)


def _change(node: str, stamp_ns: int, *changed: tuple[str, int, Any]) -> bytes:
    """A ParameterEvent of ``node`` (name, rcl_interfaces ParameterType, value each)."""
    return parameter_event_cdr(node, stamp_ns, list(changed))


def _run_status(name: str = "boom_sim: run", **values: str) -> DiagnosticArray:
    status = DiagnosticStatus(name=name, values=[KeyValue(key=k, value=v) for k, v in values.items()])
    return DiagnosticArray(status=[status])


def _setpoint(stamp_ns: int, position: float, velocity: float) -> bytes:
    """The node's setpoint: its cylinder joint first (another after it, which is not read)."""
    return cdr.joint_state(stamp_ns, ["cylinder_joint", "other"], [position, 9.0], [velocity, 9.0], [])


Message = tuple[str, str, int, Any]  # topic, type, log ns, message


def _bag(folder: Path, messages: list[Message], offers: dict[str, Any] | None = None) -> Path:
    """A bag of ``messages``, written in log order (stable: ties as listed)."""
    topics: dict[str, Topic] = {}
    for name, msgtype, _, _ in messages:
        extra = {"offers": (offers[name],)} if offers and name in offers else {}
        topics.setdefault(name, Topic(name, msgtype, **extra))
    with BagRecorder(folder, list(topics.values())) as rec:
        for name, _, log_ns, msg in sorted(messages, key=lambda m: m[2]):
            rec.write(name, log_ns, msg if isinstance(msg, bytes) else serialize_message(msg))
    return folder


def _describe(events_topic: str | None = None, node: str | None = NODE) -> RunDescription:
    return RunDescription({}, ORIGIN, 100.0, 1.0, node=node, events_topic=events_topic)


def _states(*stamps_ms: int, lag_ms: int = 1) -> list[Message]:
    """DriveStates stamped at ``stamps_ms`` after the origin, each logged ``lag_ms`` later."""
    return [
        ("/drive_state", DRIVE_STATE, ORIGIN + (s + lag_ms) * MS, _state(ORIGIN + s * MS, q=s / 1000))
        for s in stamps_ms
    ]


def test_a_node_instants_state_counts_for_a_message_logged_at_its_time_only_on_publish_clock():
    logged = [(10, 100), (20, 200)]
    shared = NodeInstants(5, logged)  # a time origin: the node logs on a clock of its own
    assert [shared.at(t) for t in (9, 10, 11, 20, 21)] == [5, 5, 100, 100, 200]
    assert [shared.count(t) for t in (9, 10, 11, 20, 21)] == [0, 0, 1, 1, 2]
    published = NodeInstants(0, logged)  # origin 0: publish_clock, log times are simulated time
    assert [published.at(t) for t in (9, 10, 11, 20, 21)] == [0, 100, 100, 200, 200]
    assert [published.count(t) for t in (9, 10, 11, 20, 21)] == [0, 1, 1, 2, 2]


def test_each_command_acts_at_its_stamp_or_where_the_node_took_it(tmp_path):
    commands = [
        ("/valve_command", VALVE_COMMAND, ORIGIN + 25 * MS, _command(0, 0.5)),  # unstamped: where the node was
        ("/valve_command", VALVE_COMMAND, ORIGIN + 26 * MS, _command(ORIGIN + 45 * MS, -0.25)),  # ahead: its stamp
        ("/valve_command", VALVE_COMMAND, ORIGIN + 31 * MS, _command(ORIGIN + 5 * MS, 1.0)),  # passed; with a state
        ("/arm/command", ARRAY_COMMAND, ORIGIN + 41 * MS + 1, Float64MultiArray(data=[0.375])),  # never stamped
        ("/arm/command", ARRAY_COMMAND, ORIGIN + 42 * MS, Float64MultiArray(data=[0.1, 0.2])),  # not one opening
        ("/arm/command", ARRAY_COMMAND, ORIGIN + 43 * MS, to_cdr(message(ARRAY_COMMAND))),  # nor is none
    ]
    transient = offered_qos(transient_local=True)
    bag = _bag(tmp_path / "bag", _states(10, 20, 30, 40) + commands, offers={"/valve_command": transient})
    run = read_run(bag, _describe())
    got = [(c.topic, c.at_ns - ORIGIN, c.stamp_ns, c.taken_ns, c.taken_after, c.log_ns) for c in run.commands]
    assert got == [
        ("/valve_command", 20 * MS, 0, ORIGIN + 20 * MS, 2, ORIGIN + 25 * MS),
        ("/valve_command", 45 * MS, ORIGIN + 45 * MS, ORIGIN + 20 * MS, 2, ORIGIN + 26 * MS),
        ("/valve_command", 20 * MS, ORIGIN + 5 * MS, ORIGIN + 20 * MS, 2, ORIGIN + 31 * MS),  # logged with state 3
        ("/arm/command", 40 * MS, 0, ORIGIN + 40 * MS, 4, ORIGIN + 41 * MS + 1),
        ("/arm/command", 40 * MS, 0, ORIGIN + 40 * MS, 4, ORIGIN + 42 * MS),
        ("/arm/command", 40 * MS, 0, ORIGIN + 40 * MS, 4, ORIGIN + 43 * MS),
    ]
    assert [c.opening for c in run.commands[:4]] == [0.5, -0.25, 1.0, 0.375] and all(
        math.isnan(c.opening) for c in run.commands[4:]
    )
    assert [bytes(c.raw) for c in run.commands] == [
        m if isinstance(m, bytes) else serialize_message(m) for *_, m in commands
    ]
    assert all(c.origin_ns == ORIGIN for c in run.commands)
    assert run.topics == [
        Topic("/valve_command", VALVE_COMMAND, (transient,)),
        Topic("/arm/command", ARRAY_COMMAND, (offered_qos(),)),
    ]
    assert run.end_ns == ORIGIN + 43 * MS + 1  # one past the last log time (rosbags' end_time)


def test_without_drive_states_a_command_acts_at_its_stamp_or_when_it_was_logged(tmp_path):
    bag = _bag(
        tmp_path / "bag",
        [
            ("/valve_command", VALVE_COMMAND, ORIGIN + 25 * MS, _command(0, 0.5)),
            ("/valve_command", VALVE_COMMAND, ORIGIN + 26 * MS, _command(ORIGIN + 45 * MS, 0.25)),
        ],
    )
    run = read_run(bag, _describe())
    assert [(c.at_ns, c.taken_ns, c.taken_after) for c in run.commands] == [
        (ORIGIN + 25 * MS, None, 0),
        (ORIGIN + 45 * MS, None, 0),
    ]
    assert run.state_ns == [] and run.state_topic == "/drive_state" and run.state_signals == ((), (), (), ())


def test_parameter_changes_of_the_node_act_at_their_stamps_with_their_values(tmp_path):
    values = [  # each ParameterType (rcl_interfaces/msg/ParameterType) once
        ("record", 1, True),
        ("turns", 2, 3),
        ("payload_kg", 3, 250.0),
        ("mode", 4, "paper"),
        ("blob", 5, [1, 127]),
        ("flags", 6, [True, False]),
        ("ids", 7, [4, 5]),
        ("gains", 8, [1.5, 2.5]),
        ("names", 9, ["a", "b"]),
    ]
    events = [
        ("/parameter_events", PARAMETER_EVENT, ORIGIN + 36 * MS, _change(NODE, ORIGIN + 35 * MS, *values)),
        ("/parameter_events", PARAMETER_EVENT, ORIGIN + 37 * MS, _change("/other", ORIGIN + 37 * MS, *values)),
        ("/parameter_events", PARAMETER_EVENT, ORIGIN + 38 * MS, _change("/arm", ORIGIN + 38 * MS, *values)),
        ("/parameter_events", PARAMETER_EVENT, ORIGIN + 50 * MS, _change(NODE, ORIGIN + 15 * MS, ("damping", 3, 0.5))),
    ]
    bag = _bag(tmp_path / "bag", _states(10, 20) + events)
    run = read_run(bag, _describe())
    assert [(c.at_ns, c.log_ns) for c in run.parameter_changes] == [
        (ORIGIN + 15 * MS, ORIGIN + 50 * MS),  # by the instant they act at
        (ORIGIN + 35 * MS, ORIGIN + 36 * MS),
    ]
    assert run.parameter_changes[0] == Recorded(  # no command's stamp, instant or count
        ORIGIN + 15 * MS,
        ORIGIN + 50 * MS,
        "/parameter_events",
        events[3][3],
        changes={"damping": 0.5},
        origin_ns=ORIGIN,
    )
    changes = run.parameter_changes[1].changes
    assert changes == {name: value for name, _, value in values}
    assert all(type(got) is type(value) for name, _, value in values for got in [changes[name]])
    assert all(  # Python's numbers, not numpy's
        type(v) is type(w) for name, _, value in values if isinstance(value, list) for v, w in zip(changes[name], value)
    )
    assert run.parameter_changes[1].raw == events[0][3] and not run.commands
    # a run whose node is not named keeps every node's changes
    assert len(read_run(bag, _describe(node=None)).parameter_changes) == 4


def test_the_setpoints_and_the_nodes_latest_counts_are_read(tmp_path):
    messages = [
        ("/joint_states", JOINT_STATE, ORIGIN + 11 * MS, _setpoint(ORIGIN + 10 * MS, 9.0, 9.0)),  # not a setpoint
        ("/notes/setpoint", "std_msgs/msg/String", ORIGIN + 11 * MS, String(data="not a JointState")),
        ("/diag/setpoint", DIAGNOSTICS, ORIGIN + 11 * MS, _run_status("not a JointState either")),
        ("/crane/boom_sim/setpoint", JOINT_STATE, ORIGIN + 12 * MS, _setpoint(ORIGIN + 30 * MS, 0.5, 0.25)),
        ("/crane2/boom_sim/setpoint", JOINT_STATE, ORIGIN + 12 * MS, _setpoint(ORIGIN + 25 * MS, 9.0, 9.0)),  # later
        ("/crane/boom_sim/setpoint", JOINT_STATE, ORIGIN + 13 * MS, _setpoint(ORIGIN + 20 * MS, 0.375, -0.125)),
        ("/diagnostics", DIAGNOSTICS, ORIGIN + 15 * MS, _run_status(step_calls="x", resets="1", pauses="2")),
        ("/diagnostics", DIAGNOSTICS, ORIGIN + 16 * MS, _run_status("boom_sim: drive", pauses="9")),  # not its run
        ("/diagnostics", DIAGNOSTICS, ORIGIN + 16 * MS, _run_status("boom_sim: stepping", step_calls="7")),
        ("/diagnostics", DIAGNOSTICS, ORIGIN + 17 * MS, _run_status(resets="3", clock_origin_shift_s="0.25", ok="1")),
    ]
    run = read_run(_bag(tmp_path / "bag", messages), _describe())
    assert run.setpoints == [(ORIGIN + 20 * MS, 0.375, -0.125), (ORIGIN + 30 * MS, 0.5, 0.25)]  # by stamp
    assert run.run_counts == {"resets": 3.0, "pauses": 2.0, "clock_origin_shift_s": 0.25}


def _path_message(path, t0_s: float, start: int) -> bytes:
    """~/setpoint_path of ``path`` as the node publishes it when it takes the path at ``t0_s``."""
    recorded = RecordedPath(
        ORIGIN + round(t0_s * 1e9),
        start,
        knot_offsets_ns(path, t0_s),
        path.angles_rad[:, 0].tolist(),
        path.rates_rad_s[:, 0].tolist(),
        path.order,
    )
    return setpoint_path_cdr("boom_joint", recorded)


def test_the_paths_the_controller_followed_read_back_bit_for_bit_where_the_node_took_them(tmp_path):
    """Each ~/setpoint_path: after the states logged before it, the path rebuilt at the node's
    instant equal to the one the node followed (its knots on whole ns from there) in every bit."""
    t0 = 0.02  # the instant of the second state (sums of time steps are seldom whole ns)
    followed = [
        (on_whole_ns(move(t0, 0.3, 0.01, 0.6, 0.37), t0), START_SETPOINT),  # a goal's quintic
        (on_whole_ns(SetpointPath.of([t0, t0 + 0.1 / 3], [0.25, 0.5], [0.125, 0.0]), t0), START_OWN),  # cubic
        (on_whole_ns(SetpointPath.of([t0, t0 + 1 / 7], [0.25, 0.5]), t0), START_OWN),  # linear
        (on_whole_ns(SetpointPath.of([t0], [0.4]), t0), START_BOOM),  # an empty trajectory's hold
    ]
    topic = "/crane/boom_sim/setpoint_path"
    paths = [
        (topic, SETPOINT_PATH, ORIGIN + 25 * MS + k, _path_message(p, t0, start))
        for k, (p, start) in enumerate(followed)
    ]
    run = read_run(_bag(tmp_path / "bag", _states(10, 20, 30) + paths), _describe())
    assert [(p.taken_after, p.log_ns - ORIGIN - 25 * MS, p.path.start) for p in run.paths] == [
        (2, k, start) for k, (_, start) in enumerate(followed)
    ]
    assert topic in [t.name for t in run.topics]  # (copied into boom-resim's bag)
    for taken, (path, _) in zip(run.paths, followed):
        r = taken.path
        again = path_from_offsets(t0, r.offsets_ns, r.angles_rad, r.rates_rad_s, r.order)
        assert again.order == path.order
        for a, b in (
            (again.times_s, path.times_s),
            (again.angles_rad, path.angles_rad),
            (again.rates_rad_s, path.rates_rad_s),
        ):
            assert a.tobytes() == b.tobytes()
    # the node's paths move a planned knot by at most half a nanosecond
    planned = move(t0, 0.3, 0.01, 0.6, 0.37)
    assert abs(followed[0][0].end_s[0] - planned.end_s[0]) <= 0.5e-9 and followed[0][0].times_s[0, 0] == t0
    # without states there is nothing to place them by; a path of two joints is not the node's
    assert read_run(_bag(tmp_path / "alone", paths), _describe()).paths == []
    two = (topic, SETPOINT_PATH, ORIGIN + 25 * MS, _two_joints(_path_message(followed[0][0], t0, START_SETPOINT)))
    with pytest.raises(BagError, match=r"a message does not fit its recorded type"):
        read_run(_bag(tmp_path / "two", [*_states(10, 20), two]), _describe())
    # another type on a topic of that name (a JointTrajectory) is no path of the node's: none read
    # (boom-resim follows its setpoints)
    bare = typestore().deserialize_cdr(_path_message(followed[0][0], t0, START_SETPOINT), SETPOINT_PATH).trajectory
    trajectory = "trajectory_msgs/msg/JointTrajectory"
    old = (topic, trajectory, ORIGIN + 25 * MS, bytes(typestore().serialize_cdr(bare, trajectory)))
    assert read_run(_bag(tmp_path / "old", [*_states(10, 20), old]), _describe()).paths == []
    # nor is one that starts from neither its own point, the setpoint nor the boom
    unknown = (topic, SETPOINT_PATH, ORIGIN + 25 * MS, _changed(_path_message(followed[0][0], t0, START_OWN), start=3))
    with pytest.raises(BagError, match=r"a message does not fit its recorded type"):
        read_run(_bag(tmp_path / "unknown", [*_states(10, 20), unknown]), _describe())


def _two_joints(data: bytes) -> bytes:
    """The path message ``data`` naming a second joint."""
    store = typestore()
    msg = store.deserialize_cdr(data, SETPOINT_PATH)
    msg.trajectory.joint_names = ["boom_joint", "other"]
    return bytes(store.serialize_cdr(msg, SETPOINT_PATH))


def _changed(data: bytes, **fields: Any) -> bytes:
    """The path message ``data`` with ``fields`` set."""
    store = typestore()
    msg = store.deserialize_cdr(data, SETPOINT_PATH)
    for name, value in fields.items():
        setattr(msg, name, value)
    return bytes(store.serialize_cdr(msg, SETPOINT_PATH))


def test_a_setpoint_without_a_position_is_one_line(tmp_path):
    empty = cdr.joint_state(ORIGIN, [], [], [], [])
    bag = _bag(tmp_path / "bag", [("/boom_sim/setpoint", JOINT_STATE, ORIGIN, empty)])
    with pytest.raises(BagError, match=r"a message does not fit its recorded type .*; was it recorded by boom_sim"):
        read_run(bag, _describe())


def test_the_states_are_in_publish_order_with_run_events_and_by_stamp_without(tmp_path):
    # the ROS clock jumped back after the second state: the third is stamped before it
    states = [
        *_states(10, 20),
        ("/drive_state", DRIVE_STATE, ORIGIN + 31 * MS, _state(ORIGIN + 15 * MS, 0.1, 2.0, 3.0, 4.0)),
    ]
    goals = [("/arm/status", "action_msgs/msg/GoalStatusArray", ORIGIN, GoalStatusArray())]  # first, not a state
    ledger = [("/crane/boom_sim/ledger", ENERGY_LEDGER, ORIGIN + 11 * MS, EnergyLedger())]
    another = [("/crane2/drive_state", DRIVE_STATE, ORIGIN + 12 * MS, _state(ORIGIN + 11 * MS))]  # not read
    bag = _bag(tmp_path / "bag", goals + states + ledger + another)
    by_stamp = read_run(bag, _describe())
    assert by_stamp.state_ns == [ORIGIN + 10 * MS, ORIGIN + 15 * MS, ORIGIN + 20 * MS]
    assert by_stamp.state_log_ns == [ORIGIN + 11 * MS, ORIGIN + 31 * MS, ORIGIN + 21 * MS]
    assert by_stamp.state_signals == ([0.01, 0.1, 0.02], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0], [0.0, 4.0, 0.0])
    assert by_stamp.energy_topic == "/crane/boom_sim/ledger" and by_stamp.state_topic == "/drive_state"
    logged = read_run(bag, _describe(events_topic="/crane/boom_sim/events"))
    assert logged.state_ns == [ORIGIN + 10 * MS, ORIGIN + 20 * MS, ORIGIN + 15 * MS]
    assert logged.state_log_ns == [ORIGIN + 11 * MS, ORIGIN + 21 * MS, ORIGIN + 31 * MS]
    assert logged.has_events and not by_stamp.has_events and logged.events == []


def test_the_energy_topic_is_the_nodes_own_where_no_ledger_was_recorded(tmp_path):
    command = ("/valve_command", VALVE_COMMAND, ORIGIN + 15 * MS, _command(0, 0.5))
    bag = _bag(tmp_path / "bag", [*_states(10), command])
    assert read_run(bag, _describe()).energy_topic == f"{NODE}/energy"
    assert read_run(bag, _describe(node=None)).energy_topic is None


def test_each_state_command_and_change_has_the_time_origin_of_the_run_events_before_it(tmp_path):
    dropped = RunEvent("backlog_dropped", 0.01, 1, ORIGIN + 5 * MS, origin_moved_ns=5 * MS, dropped_s=0.005)
    reset = RunEvent("reset", 0.0, 3, ORIGIN + 30 * MS, origin_moved_ns=30 * MS, cause="reset", stopped=False)
    topic = f"{NODE}/events"
    events = [
        (topic, "std_msgs/msg/String", ORIGIN + 12 * MS, String(data=dropped.to_json())),
        (topic, "std_msgs/msg/String", ORIGIN + 32 * MS, String(data=reset.to_json())),
    ]
    after = [
        ("/valve_command", VALVE_COMMAND, ORIGIN + 32 * MS, _command(0, 0.5)),  # logged with the reset: after it
        ("/parameter_events", PARAMETER_EVENT, ORIGIN + 32 * MS - 1, _change(NODE, ORIGIN + 32 * MS, ("a", 3, 1.0))),
        ("/valve_command", VALVE_COMMAND, ORIGIN + 45 * MS, _command(0, 0.25)),
    ]
    states = [*_states(10, 20, 30), ("/drive_state", DRIVE_STATE, ORIGIN + 41 * MS, _state(ORIGIN + 40 * MS))]
    run = read_run(_bag(tmp_path / "bag", states + events + after), _describe(events_topic=topic))
    assert run.events == [dropped, reset]
    assert run.event_messages == [(log, serialize_message(msg)) for _, _, log, msg in events]
    assert [c.origin_ns for c in run.commands] == [ORIGIN + 30 * MS, ORIGIN + 30 * MS]
    assert [c.origin_ns for c in run.parameter_changes] == [ORIGIN + 5 * MS]  # logged 1 ns before the reset
    assert run.state_origins_ns() == [ORIGIN, ORIGIN + 5 * MS, ORIGIN + 5 * MS, ORIGIN + 30 * MS]
    assert [run.state_origin_ns(i) for i in range(4)] == run.state_origins_ns()
    assert [round(run.state_sim_s(i), 12) for i in range(4)] == [0.01, 0.015, 0.025, 0.01]


def test_a_run_event_that_does_not_read_and_a_cut_bag_are_one_line(tmp_path):
    topic = f"{NODE}/events"
    bag = _bag(tmp_path / "bag", [(topic, "std_msgs/msg/String", ORIGIN, String(data='{"event": "nap"}'))])
    with pytest.raises(BagError, match=rf"a run event on {topic} does not read .*; the bag is not whole"):
        read_run(bag, _describe(events_topic=topic))
    file = next(bag.glob("*.mcap"))
    file.write_bytes(file.read_bytes()[:30])
    with pytest.raises(BagError, match=r"cannot read the bag .*; is it truncated or not a rosbag2/MCAP bag"):
        read_run(bag, _describe())


def test_a_reset_after_hundreds_of_states_moves_the_origin_of_those_after_it(tmp_path):
    """Three seconds of states every 10 ms: stamps of whole seconds and nanoseconds, and a reset after the 300th."""
    reset = RunEvent("reset", 0.0, 300, ORIGIN + 3 * MS, origin_moved_ns=3 * MS, cause="reset", stopped=False)
    topic = f"{NODE}/events"
    events = [(topic, "std_msgs/msg/String", ORIGIN + 2995 * MS, String(data=reset.to_json()))]
    change = _change(NODE, ORIGIN + 2500 * MS + 7, ("a", 3, 1.0))
    changes = [("/parameter_events", PARAMETER_EVENT, ORIGIN + 2501 * MS, change)]
    messages = [*_states(*range(0, 3020, 10), lag_ms=0), *events, *changes]
    run = read_run(_bag(tmp_path / "bag", messages), _describe(events_topic=topic))
    assert run.state_ns[-1] == ORIGIN + 3010 * MS and run.parameter_changes[0].at_ns == ORIGIN + 2500 * MS + 7
    assert run.state_origins_ns()[298:] == [ORIGIN, ORIGIN, ORIGIN + 3 * MS, ORIGIN + 3 * MS]


def test_a_run_of_hundreds_of_steps_reads_back_with_the_origin_of_the_last(tmp_path):
    topic = f"{NODE}/events"
    steps = [RunEvent("step", 0.01, 1, ORIGIN + k * 1000, origin_moved_ns=1000, steps=1) for k in range(1, 301)]
    events = [(topic, "std_msgs/msg/String", ORIGIN + 12 * MS, String(data=e.to_json())) for e in steps]
    run = read_run(_bag(tmp_path / "bag", [*_states(10, 20), *events]), _describe(events_topic=topic))
    assert len(run.events) == 300 and run.state_origins_ns() == [ORIGIN, ORIGIN + 300_000]
