"""The node's default clock (ROS time, no publish_clock): commands act at their stamps, a
bag re-simulates, stale commands are refused, and the node ends as a robot stack ends it."""

from __future__ import annotations

import math
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from conftest import BOOM_SIM, run_tool, start_node, stop_process

rclpy = pytest.importorskip("rclpy")
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics_msgs.srv import Step  # noqa: E402

RESIM = shutil.which("boom-resim")
pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None or RESIM is None, reason="run through tools/with-env"),
]
TICK_S, DT_S = 0.01, 0.001  # config/default.yaml: 100 Hz, 1 ms steps


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _states(bag: Path) -> list[tuple[int, float, float]]:
    """(header stamp ns, rod position m, valve command) of each recorded DriveState."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == "/drive_state"]
        rows = []
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            rows.append((_ns(msg.header.stamp), msg.rod_position_m, msg.valve_command))
    return rows


def test_a_command_stamped_ahead_acts_at_its_stamp_and_the_bag_resimulates(nodes, client, tmp_path):
    proc = nodes.start(f"record_folder:={tmp_path / 'bags'}", "command_timeout_s:=0.0", record=True)
    try:
        client.handshake()  # discovery done both ways, no command left on the way
        # a second ahead of the node's clock, the system clock (the newest state this client has
        # taken may be older than that on a loaded machine)
        stamp_ns = time.time_ns() + 1_000_000_000
        client.command(0.6, stamp_s=stamp_ns * 1e-9)
        client.command(-0.4, stamp_s=(stamp_ns + 600_000_000) * 1e-9)
        assert client.spin_until(lambda: client.last().valve_command == -0.4, timeout=30)
        client.spin_for(0.2)
    finally:
        out = stop_process(proc)
    assert proc.returncode == 0, out
    (bag,) = (tmp_path / "bags").iterdir()
    origin_ns = int(
        yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]["custom_data"][
            "clock_origin_ns"
        ]
    )
    states = _states(bag)
    # a state's stamp is the node-clock time of its simulated instant
    assert (states[0][0] - origin_ns) * 1e-9 < 1.0  # the bag starts with the stepping, not before
    planned = ((0.6, stamp_ns), (-0.4, stamp_ns + 600_000_000))
    # a tick that a loaded machine delays publishes one state for all the steps it catches up, so
    # the 0.6 s of the first opening may show in no state; the last one must
    shown = [(o, at) for o, at in planned if any(s[2] == o for s in states)]
    assert shown and shown[-1][0] == -0.4
    for opening, at_ns in shown:
        first = next(i for i, s in enumerate(states) if s[2] == opening)
        before, after = states[first - 1][0], states[first][0]
        # acted at the step that starts within half a step of the stamp: between these two states
        assert before <= at_ns + DT_S * 0.5e9 and after >= at_ns - DT_S * 0.5e9 + DT_S * 1e9, (before, at_ns, after)
    # an unchanged re-simulation of this default-clock bag reproduces it
    result = run_tool("boom-resim", bag, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    again = {ns: q1 for ns, q1, _ in _states(tmp_path / "again")}
    common = [(q1, again[ns]) for ns, q1, _ in states if ns in again]
    assert len(common) > 0.9 * len(states)
    assert max(abs(a - b) for a, b in common) < 1e-6


def _stamps_ahead_of_the_clock(client, states: int) -> list[float]:
    """How far each of the next ``states`` drive states' stamps lie ahead of the system clock
    (the node's clock) when this client takes them, s: a stamp is the node-clock time of a
    simulated instant the node has reached, so never ahead of it."""
    ahead: list[float] = []
    seen = len(client.states)

    def taken() -> bool:
        nonlocal seen
        now_ns = time.time_ns()
        ahead.extend((_ns(s.header.stamp) - now_ns) * 1e-9 for s in client.states[seen:])
        seen = len(client.states)
        return len(ahead) >= states

    assert client.spin_until(taken), f"{len(ahead)} states"
    return ahead


def _acts_at_its_stamp(client, opening: float, ahead_s: float) -> None:
    """A command stamped ``ahead_s`` ahead of the node's clock acts at the step that starts
    within half a step of its stamp: between the two states around it."""
    stamp_ns = time.time_ns() + round(ahead_s * 1e9)
    sent = len(client.states)
    client.command(opening, stamp_s=stamp_ns * 1e-9)
    assert client.spin_until(lambda: client.last().valve_command == opening, timeout=30), "it never acted"
    states = client.states[sent - 1 :]
    first = next(i for i, s in enumerate(states) if s.valve_command == opening)
    before, after = _ns(states[first - 1].header.stamp), _ns(states[first].header.stamp)
    assert before <= stamp_ns + DT_S * 0.5e9, ((before - stamp_ns) * 1e-9, "acted before its stamp")
    assert after >= stamp_ns + DT_S * 0.5e9, ((after - stamp_ns) * 1e-9, "the state it first shows in")


def test_a_reset_keeps_the_stamps_on_the_clock(nodes, client):
    """~/reset takes no simulated time: the states' stamps stay the node clock's (they ran
    ahead of it by the time since the start), and a command stamped ahead acts at its stamp
    after a reset as before it."""
    from boom_hydraulics_msgs.srv import Reset

    proc = nodes.start("command_timeout_s:=0.0")
    try:
        client.handshake()
        client.spin_sim(1.5)  # simulated time far beyond what one tick could hide
        _acts_at_its_stamp(client, 0.3, 0.5)
        for k in range(2):
            assert client.call(client.reset, Reset.Request()).success
            ahead = _stamps_ahead_of_the_clock(client, 30)
            assert max(ahead) <= 1e-3, (f"after reset {k + 1}", max(ahead))
            _acts_at_its_stamp(client, 0.2 + 0.1 * k, 0.5)
    finally:
        stop_process(proc)


def test_a_new_mode_keeps_the_stamps_on_the_clock(nodes, client):
    """A change of mode resets the state (another state vector) and takes no simulated time,
    as ~/reset: the stamps stay the node clock's."""
    proc = nodes.start("command_timeout_s:=0.0")
    try:
        client.handshake()
        client.spin_sim(1.5)
        paper = Parameter(name="mode", value=ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="paper"))
        assert client.call(client.set_params, SetParameters.Request(parameters=[paper])).results[0].successful
        ahead = _stamps_ahead_of_the_clock(client, 30)
        assert max(ahead) <= 1e-3, ("after mode paper", max(ahead))
        _acts_at_its_stamp(client, 0.6, 0.5)
    finally:
        stop_process(proc)


def test_a_stale_command_is_refused_with_the_reason_and_counted(nodes, client, tmp_path):
    proc = nodes.start("command_timeout_s:=1.0", f"record_folder:={tmp_path / 'bags'}", record=True)
    try:
        client.handshake()  # discovery done both ways, no command left on the way
        # stamps on the node's clock, the system clock: the newest state this client has taken
        # may be older than that on a loaded machine
        client.command(0.7, stamp_s=time.time() - 3.0)  # 3 s old: older than the timeout
        assert client.spin_until(lambda: client.status_values("commands").get("stale") == "1")
        assert all(s.valve_command != 0.7 for s in client.states)  # it never acted
        client.command(0.3, stamp_s=time.time() - 0.1)  # late, not stale
        assert client.spin_until(lambda: client.last().valve_command == 0.3)
    finally:
        out = stop_process(proc)
    assert "older than command_timeout_s = 1 s, it is stale" in out
    # boom-resim applies the same rule: the stale command never acts there either
    (bag,) = (tmp_path / "bags").iterdir()
    result = run_tool("boom-resim", bag, "--out", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    valves = {valve for _, _, valve in _states(tmp_path / "again")}
    assert 0.3 in valves and 0.7 not in valves


def test_use_sim_time_is_start_only_and_step_is_bounded(node, client):
    assert client.spin_until(lambda: len(client.states) > 5, timeout=60)
    flag = Parameter(name="use_sim_time", value=ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=True))
    result = client.call(client.set_params, SetParameters.Request(parameters=[flag])).results[0]
    assert not result.successful and "use_sim_time is start-only" in result.reason
    assert client.call(client.pause, SetBool.Request(data=True)).success
    huge = client.call(client.step, Step.Request(steps=4294967295))
    assert not huge.success and "call ~/step again" in huge.message
    one_more = client.call(client.step, Step.Request(steps=10_001))  # one step past 10 s of them
    assert not one_more.success and "(10000 steps of 0.001 s)" in one_more.message
    t0 = one_more.sim_time_s
    largest = client.call(client.step, Step.Request(steps=10_000))  # the largest call taken: 10 s
    assert largest.success and math.isclose(largest.sim_time_s - t0, 10.0, abs_tol=1e-9)
    small = client.call(client.step, Step.Request(steps=25))
    assert small.success and math.isclose(small.sim_time_s - largest.sim_time_s, 25 * DT_S, abs_tol=1e-9)
    assert client.spin_until(lambda: client.status_values("run").get("step_calls") == "2", timeout=30)
    assert client.status_values("run")["pauses"] == "1"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_two_signals_at_once_still_finish_the_bag_with_status_0(client, tmp_path, sig):
    """A terminal's Ctrl-C and the one ros2 launch forwards arrive together."""
    proc = start_node(f"record_folder:={tmp_path}", record=True)
    try:
        assert client.spin_until(lambda: len(client.states) > 5, timeout=60)
    finally:
        proc.send_signal(sig)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert "Traceback" not in out
    (bag,) = tmp_path.iterdir()
    assert (bag / "metadata.yaml").is_file()
    assert len(_states(bag)) > 5


def test_a_second_signal_that_lands_while_the_shield_goes_up_is_taken_by_it(monkeypatch):
    """The two-signal case above at its worst moment (make test met it once): the second
    signal's KeyboardInterrupt comes out of the shield's own signal.signal call. The shield
    goes up again, whole: both signals then only say the node is still finishing."""
    from boom_hydraulics.ros import process

    installed: dict[int, object] = {}

    def landing_once(signum, handler):
        if not installed and not landing_once.landed:
            landing_once.landed = True
            raise KeyboardInterrupt  # the second signal, as Python raises it there
        installed[signum] = handler

    landing_once.landed = False
    monkeypatch.setattr(process.signal, "signal", landing_once)
    try:
        process._shield_signals()
    except KeyboardInterrupt:  # (caught: pytest would take it as the user's and end the run)
        pytest.fail("the second signal came out of the shield: a traceback, and the bag left unfinished")
    assert landing_once.landed and set(installed) == {signal.SIGINT, signal.SIGTERM}
    assert installed[signal.SIGINT] is installed[signal.SIGTERM]


def test_commands_a_flood_drops_are_counted_in_diagnostics(node, client):
    """The sensor-data queue keeps the last few commands of a flood; what it drops is counted."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from boom_hydraulics_msgs.msg import ValveCommand

    flood = client.node.create_publisher(
        ValveCommand, "valve_command", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    assert client.spin_until(lambda: flood.get_subscription_count() > 0, timeout=60)
    client.node.destroy_publisher(
        client.pub
    )  # the flood's publisher is the topic's only one: its sequence numbers tell the gaps

    def counts() -> tuple[int, int]:
        values = client.status_values("commands")
        return int(values.get("received", 0)), int(values.get("lost", 0))

    def send_until_received() -> bool:
        flood.publish(ValveCommand(opening=0.0))
        return client.spin_until(lambda: counts()[0] > 0, timeout=0.2)

    assert client.spin_until(send_until_received, timeout=30)  # discovery is complete both ways
    client.diagnostics.clear()
    assert client.spin_until(lambda: len(client.diagnostics) >= 2, timeout=30)  # it has seen the lone publisher
    before = counts()
    sent = 20_000
    for _ in range(sent):
        flood.publish(ValveCommand(opening=0.0))
    client.spin_for(0.5)
    flood.publish(ValveCommand(opening=0.0))  # the last one shows a gap at the flood's end too

    def accounted() -> bool:  # (the middleware may drop some before the sequence numbers can tell)
        received, lost = counts()
        return received - before[0] + lost - before[1] >= 0.95 * (sent + 1)

    assert client.spin_until(accounted, timeout=60), (before, counts())
    received, lost = counts()
    assert received - before[0] + lost - before[1] <= sent + 1, (before, counts())
    assert int(client.status_values("commands")["lost"]) > 0


def _loading_rclpy(proc: subprocess.Popen) -> bool:
    """Whether the process has begun loading rclpy's native module (inside boom_sim's guard)."""
    try:
        return "_rclpy_pybind11" in Path(f"/proc/{proc.pid}/maps").read_text()
    except OSError:
        return False


def _wait_for(predicate, proc: subprocess.Popen, timeout_s: float = 60.0) -> None:
    import time

    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert proc.poll() is None and time.monotonic() < deadline, "the node ended or never got there"
        time.sleep(0.005)


@pytest.mark.parametrize("moment", ["loading", "starting"])
def test_a_ctrl_c_during_start_up_ends_without_a_traceback(moment, tmp_path):
    """Whether it lands while the node's modules load (rclpy, numba) and the model compiles,
    or as its stepping and its bag start (right after its first log line): one line or none,
    status 0, no traceback, and no bag, or a finished one. (Before boom_sim's own code runs,
    Python's start-up is as every console script's.)"""
    proc = subprocess.Popen(
        [BOOM_SIM, "--ros-args", "-p", "record:=true", "-p", f"record_folder:={tmp_path}"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    if moment == "loading":
        _wait_for(lambda: _loading_rclpy(proc), proc)
    else:
        line = proc.stdout.readline()  # its first log line: start() comes next
        assert " mode, " in line, line
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=60)
    assert "Traceback" not in out and "KeyboardInterrupt" not in out, out
    assert proc.returncode == 0, out
    bags = list(tmp_path.iterdir())
    assert len(bags) <= 1 and all((bag / "metadata.yaml").is_file() for bag in bags), (bags, out)
