"""boom-resim reproduces every run the node recorded, whatever the node did to its own time
line: the node records each of its run events (a dropped backlog, a pause, steps, a resume, a
reset) on ~/events, and boom-resim replays them where they happened."""

from __future__ import annotations

import json
import os
import signal
import time

import numpy as np
import pytest
from conftest import BOOM_SIM, GUARD_S, run_tool, stop_process

rclpy = pytest.importorskip("rclpy")
from rclpy.action import ActionClient  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics.bags.reading import read_custom_data  # noqa: E402
from boom_hydraulics.bags.run_events import parse  # noqa: E402
from boom_hydraulics_msgs.action import MoveBoom  # noqa: E402
from boom_hydraulics_msgs.srv import Reset, Step  # noqa: E402

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]


def _states(bag) -> list[tuple[int, float, float]]:
    """(stamp ns, rod position m, valve command) of each recorded DriveState, in the order recorded."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/drive_state"]
        rows = []
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            rows.append((stamp, msg.rod_position_m, msg.valve_command))
    return rows


def _resimulates_exactly(bag, out, log: str) -> list[tuple[int, float, float]]:
    """boom-resim of ``bag`` into ``out`` gives every recorded state again: the same stamps (time
    origins moved as they moved), each command where it acted, the rod to 1e-9 m; the states."""
    result = run_tool("boom-resim", bag, "--out", out)
    assert result.returncode == 0, result.stderr + log
    original, again = _states(bag), _states(out)
    assert len(again) == len(original)
    assert [s[0] for s in again] == [s[0] for s in original]
    assert [s[2] for s in again] == [s[2] for s in original]
    assert max(abs(a[1] - b[1]) for a, b in zip(original, again)) < 1e-9
    return original


def _recorded_events(bag) -> list[dict]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/boom_sim/events"]
        return [json.loads(reader.deserialize(raw, c.msgtype).data) for c, _, raw in reader.messages(connections)]


@pytest.mark.parametrize("clock", ["default", "publish_clock"])
def test_a_run_with_a_stall_a_pause_steps_and_a_reset_resimulates_exactly(nodes, client, tmp_path, clock):
    """A run of the node through everything it does to its time line, re-simulated to 1e-9 m
    at every state it recorded: a stall of its process (the node drops the backlog beyond
    max_catch_up_s, which moves the time origin of ROS-time stamps), a pause with commands
    and ~/step calls in it, a resume, and a reset to another rod length with a command stamped
    ahead after it."""
    events: list[dict] = []
    subscription = client.node.create_subscription(
        String, "/boom_sim/events", lambda m: events.append(json.loads(m.data)), 100
    )
    extra = ("publish_clock:=true",) if clock == "publish_clock" else ()
    proc = nodes.start(
        f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", "max_catch_up_s:=0.2", *extra, record=True
    )

    def seen(kind: str, n: int = 1) -> bool:
        return sum(e["event"] == kind for e in events) >= n

    try:
        client.handshake()
        assert client.spin_until(lambda: subscription.get_publisher_count() > 0)  # ~/events found too
        client.command(1.0)
        client.spin_sim(0.4)
        # a stall: the node's process stopped for longer than max_catch_up_s, then it goes on
        os.kill(proc.pid, signal.SIGSTOP)
        time.sleep(0.6)  # (the stall itself, not a wait for something)
        os.kill(proc.pid, signal.SIGCONT)
        assert client.spin_until(lambda: seen("backlog_dropped")), events
        client.spin_sim(0.2)
        _pause_step_resume_and_reset(client)
        states = len(client.states)
        assert client.spin_until(lambda: len(client.states) > states + 3)
        ahead_s = 0.25 if clock == "publish_clock" else None
        stamp_s = client.sim_s() + ahead_s if ahead_s else time.time() + 0.25
        client.command(0.7, stamp_s=stamp_s)
        assert client.spin_until(lambda: client.last().valve_command == 0.7)
        client.spin_sim(0.3)
        client.command(0.0)
        assert client.spin_until(lambda: client.last().valve_command == 0.0)
        assert client.spin_until(lambda: seen("reset"))
    finally:
        log = stop_process(proc)
    (bag,) = (tmp_path / "bags").iterdir()
    recorded = _recorded_events(bag)
    # what ~/events said is what the bag holds (this client may have found the topic after its first events)
    assert events and recorded[-len(events) :] == events, (recorded, events)
    kinds = [e["event"] for e in recorded]
    assert {"backlog_dropped", "pause", "step", "resume", "reset"} <= set(kinds), kinds
    # the stall's (a loaded machine may drop small backlogs as well): each moved the origin by its backlog
    drops = [parse(json.dumps(e)) for e in recorded if e["event"] == "backlog_dropped"]
    assert max(d.dropped_s for d in drops) > 0.2, drops
    for d in drops:
        assert d.origin_moved_ns == (0 if clock == "publish_clock" else round(d.dropped_s * 1e9)), d
    reset = next(e for e in recorded if e["event"] == "reset")
    assert reset["rod_position_m"] == 1.45 and reset["state"][0] == 1.45 and reset["cause"] == "~/reset"
    assert read_custom_data(bag)["events_topic"] == "/boom_sim/events"

    original = _resimulates_exactly(bag, tmp_path / "again", log)
    # the reset shows: the rod at 1.45 m after it, where it had been lifted before
    q1 = np.array([s[1] for s in original])
    assert np.any(np.abs(q1 - 1.45) < 1e-9) and q1.max() > 1.45
    # and boom-resim's own bag re-simulates the same (the events go with it)
    result = run_tool("boom-resim", tmp_path / "again", "--out", tmp_path / "once_more")
    assert result.returncode == 0, result.stderr
    assert max(abs(a[1] - b[1]) for a, b in zip(_states(tmp_path / "again"), _states(tmp_path / "once_more"))) < 1e-12


def _pause_step_resume_and_reset(client) -> None:
    """What both scenarios do to the node's time line after their first moves: a pause with a
    command received in it (it acts at the next step) and three ~/step calls, a resume, and a
    reset to 1.45 m 0.3 s of simulated time later."""
    assert client.call(client.pause, SetBool.Request(data=True)).success
    client.command(-0.5)
    for _ in range(3):
        assert client.call(client.step, Step.Request(steps=7)).success
    assert client.call(client.pause, SetBool.Request(data=False)).success
    client.spin_sim(0.3)
    assert client.call(client.reset, Reset.Request(use_rod_position=True, rod_position_m=1.45)).success


def test_a_run_on_a_shared_clock_with_a_pause_steps_and_a_reset_resimulates_exactly(nodes, client, tmp_path):
    """Under use_sim_time (a /clock from another process), with a MoveBoom goal taken before the
    first /clock (the bag keeps its path: the controller drives from simulated time 0), commands
    stamped ahead on that clock (the first takes over from the goal) and unstamped ones (acting
    where the node took them: it takes commands at the states it published), a pause with a
    command and ~/step calls in it, a resume (which moves the time origin on by the pause) and a
    reset, re-simulated to 1e-9 m at every recorded state."""
    import subprocess
    import sys
    from pathlib import Path

    from rosgraph_msgs.msg import Clock

    clock_s: list[float] = []
    client.node.create_subscription(
        Clock,
        "/clock",
        lambda m: clock_s.append(m.clock.sec + m.clock.nanosec * 1e-9),
        rclpy.qos.qos_profile_sensor_data,
    )
    proc = nodes.start(
        "use_sim_time:=true", f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", record=True
    )
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    goal = ActionClient(client.node, MoveBoom, "/boom_sim/move_boom")
    assert goal.wait_for_server(timeout_sec=GUARD_S)
    accepted = goal.send_goal_async(MoveBoom.Goal(target_angle_rad=0.6))
    assert client.spin_until(accepted.done) and accepted.result().accepted
    source = subprocess.Popen(
        [sys.executable, str(Path(__file__).with_name("clock_source.py")), "100.0", "1.0:60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )

    def command_ahead(opening: float) -> None:
        """``opening``, stamped 0.3 s ahead of the /clock this client has seen last: it acts at its stamp."""
        client.command(opening, stamp_s=clock_s[-1] + 0.3)
        assert client.spin_until(lambda: client.last().valve_command == opening), f"{opening} never acted"

    try:
        assert client.spin_until(lambda: bool(client.states) and client.sim_s() > 100.2 and bool(clock_s), timeout=60)
        command_ahead(1.0)
        client.spin_sim(0.3)
        client.command(0.4)  # unstamped: acts where the node takes it
        assert client.spin_until(lambda: client.last().valve_command == 0.4)
        client.spin_sim(0.2)
        _pause_step_resume_and_reset(client)
        client.spin_sim(0.1)
        command_ahead(0.7)
        client.spin_sim(0.3)
        command_ahead(0.0)
    finally:
        stop_process(source)
        log = stop_process(proc)
    (bag,) = (tmp_path / "bags").iterdir()
    kinds = [e["event"] for e in _recorded_events(bag)]
    assert kinds == ["pause", "step", "step", "step", "resume", "reset"], kinds
    original = _resimulates_exactly(bag, tmp_path / "again", log)
    assert original[0][2] != 0.0  # the goal's controller drove the valve from the first state on


def test_a_run_that_blew_up_and_was_reset_resimulates_exactly(nodes, client, tmp_path):
    """Paper mode has no end stops: fig. 8's valve held open leaves the valid geometry after
    2.2 s, the node stops stepping and waits for ~/reset. The reset's event says the simulation
    had stopped; the re-simulation stops where the node did, resets there and goes on."""
    proc = nodes.start(
        f"record_folder:={tmp_path / 'bags'}",
        "publish_clock:=true",
        "real_time_factor:=4.0",
        "command_timeout_s:=0.0",
        config_file="paper_fig8.yaml",
        record=True,
    )

    def stopped() -> bool:
        return any(s.level == b"\x02" and "stopped" in s.message for d in client.diagnostics for s in d.status)

    try:
        client.handshake()
        client.command(1.0)
        assert client.spin_until(stopped)
        assert client.call(client.reset, Reset.Request()).success
        client.command(0.5)
        assert client.spin_until(lambda: client.last().valve_command == 0.5)
        client.spin_sim(0.3)
        client.command(0.0)
        assert client.spin_until(lambda: client.last().valve_command == 0.0)
    finally:
        log = stop_process(proc)
    (bag,) = (tmp_path / "bags").iterdir()
    reset = next(e for e in _recorded_events(bag) if e["event"] == "reset")
    assert reset["stopped"] is True, reset
    _resimulates_exactly(bag, tmp_path / "again", log)


def test_a_run_whose_shared_clock_jumped_back_resimulates_exactly(nodes, client, tmp_path):
    """Under use_sim_time a /clock that jumps back (a world reset) resets the drive: the reset's
    event holds the time origin after it, and the re-simulation resets there and goes on."""
    import subprocess
    import sys
    from pathlib import Path

    proc = nodes.start(
        "use_sim_time:=true", f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", record=True
    )
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    source = subprocess.Popen(
        [sys.executable, str(Path(__file__).with_name("clock_source.py")), "50.0", "1.0:2", "jump:10.0", "1.0:3"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert client.spin_until(lambda: bool(client.states), timeout=60)
        client.command(1.0)  # lift, unstamped
        assert client.spin_until(lambda: client.last().rod_position_m > 1.4)
        assert client.spin_until(lambda: client.sim_s() < 20.0), "no state after the jump"
        client.command(0.5)
        assert client.spin_until(lambda: client.last().valve_command == 0.5)
        client.spin_sim(0.3)
        source.communicate(timeout=60)
    finally:
        stop_process(source)
        log = stop_process(proc)
    assert "the ROS clock jumped back" in log
    (bag,) = (tmp_path / "bags").iterdir()
    reset = next(e for e in _recorded_events(bag) if e["event"] == "reset")
    assert reset["cause"] == "the ROS clock jumped back" and reset["origin_moved_ns"] < -30e9, reset
    _resimulates_exactly(bag, tmp_path / "again", log)


def test_a_closed_loop_run_after_a_pause_resimulates_on_the_moved_origin(nodes, client, tmp_path):
    """On the node's default clock a resume moves the time origin on by the pause; the position
    controller's recorded setpoints after it are stamped on the moved origin, and boom-resim's
    controller follows them there: unchanged within 0.1 degrees, as such a run without a pause
    re-simulates (0.055 degrees seen where the joint command's move begins, the setpoint
    interpolated between ticks); on the origin of the start it was 6 degrees off."""
    import math

    from sensor_msgs.msg import JointState

    from boom_hydraulics.bags.reading import read_drive_states

    proc = nodes.start(f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", record=True)
    joints = client.node.create_publisher(JointState, "joint_commands", 10)
    try:
        client.handshake()
        assert client.call(client.pause, SetBool.Request(data=True)).success
        arrays = len(client.diagnostics)
        assert client.spin_until(lambda: len(client.diagnostics) >= arrays + 2)  # the node's next second, paused
        assert client.call(client.step, Step.Request(steps=5)).success
        assert client.call(client.pause, SetBool.Request(data=False)).success
        assert client.spin_until(lambda: joints.get_subscription_count() > 0)
        joints.publish(JointState(name=["boom_joint"], position=[0.35]))
        assert client.spin_until(lambda: abs(client.last().boom_angle_rad - 0.35) < 0.01), client.last()
        client.spin_sim(0.3)
    finally:
        log = stop_process(proc)
    (bag,) = (tmp_path / "bags").iterdir()
    resume = next(e for e in _recorded_events(bag) if e["event"] == "resume")
    assert resume["origin_moved_ns"] > 100_000_000, resume  # the pause's wall time
    result = run_tool("boom-resim", bag, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr + log
    original, again = read_drive_states(bag), read_drive_states(tmp_path / "again")
    assert len(again["alpha"]) == len(original["alpha"])
    assert np.max(np.abs(original["alpha"] - again["alpha"])) < math.radians(0.1)
