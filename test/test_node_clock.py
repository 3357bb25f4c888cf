"""The node on a shared clock: use_sim_time:=true with /clock from a separate process."""

from __future__ import annotations

import itertools
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import BOOM_SIM, stop_process

rclpy = pytest.importorskip("rclpy")

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]

CLOCK_SOURCE = Path(__file__).with_name("clock_source.py")


def _clock_source(*phases: str) -> subprocess.Popen:
    """clock_source.py in a process of its own (see there for the phases)."""
    return subprocess.Popen(
        [sys.executable, str(CLOCK_SOURCE), *phases], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _sim_time(diagnostic) -> float:
    drive = next(s for s in diagnostic.status if s.name == "boom_sim: drive")
    return float(next(kv.value for kv in drive.values if kv.key == "sim_time_s"))


def _wall_stamps(client, seconds: float, until: subprocess.Popen | None = None) -> list[tuple[float, float]]:
    """(wall s, stamp s) of every drive_state received over ``seconds`` of wall time, or until
    the process ``until`` ends (and half a second more), whichever comes first."""
    seen: list[tuple[float, float]] = []
    start = len(client.states)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if until is not None and until.poll() is not None:
            end, until = min(end, time.monotonic() + 0.5), None
        rclpy.spin_once(client.node, timeout_sec=0.01)
        now = time.monotonic()
        seen += [(now, _stamp_s(m)) for m in client.states[start:]]
        start = len(client.states)
    return seen


def _phases(output: str) -> dict[str, float]:
    """The clock source's phase starts: {'0.5': clock s, '0.0': ..., 'end': ...}."""
    starts = {}
    for line in output.splitlines():
        words = line.split()
        if words and words[0] == "phase":
            starts[str(float(words[1]))] = float(words[3])
        elif words and words[0] == "end":
            starts["end"] = float(words[1])
    return starts


def test_the_physics_follows_an_external_clock_at_half_and_double_speed_and_stops_with_it(nodes, client):
    node = nodes.start("use_sim_time:=true", "command_timeout_s:=0")
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    source = _clock_source("100.0", "0.5:4", "0:3", "2.0:3")
    try:
        samples = _wall_stamps(client, 40.0, until=source)
        phases = _phases(source.communicate(timeout=10)[0])
    finally:
        stop_process(source)
        log = stop_process(node)
    pause_s, double_s = phases["0.0"], phases["2.0"]
    half = [(w, s) for w, s in samples if 100.3 < s < pause_s - 0.1]
    double = [(w, s) for w, s in samples if double_s + 0.3 < s < phases["end"] - 0.1]
    # stamps are the ROS clock's: the external clock's 100 s and on, not wall time and not zero
    assert min(s for _, s in samples) >= 100.0 and max(s for _, s in samples) <= phases["end"] + 0.01
    # that simulated time kept the clock's pace, half and double, is the diagnostics' check below
    # (stamp and simulated time of one message); against this client's wall time a loaded
    # machine would distort it, as this client takes the states late, then in a burst
    assert len(half) > 50 and len(double) > 50
    # states come at publish_rate_hz of the clock's time, whatever its pace: 10 ms of it apart
    for phase in (half, double):
        spacings = sorted(b - a for (_, a), (_, b) in itertools.pairwise(phase))
        assert spacings[len(spacings) // 2] == pytest.approx(0.01, abs=1e-6), spacings
    # a stopped clock stops the physics: nothing is published for the 3 s it stands still
    # (the largest wall-time gap between states stamped near the stop: which state is the last
    # before it depends on where the clock's last tick fell between two publishing instants)
    near = sorted(w for w, s in samples if abs(s - pause_s) < 0.05)
    assert max(b - a for a, b in itertools.pairwise(near)) > 2.0, near
    # simulated time advanced as the clock did: diagnostics (every second of ROS time) agree
    pairs = [
        (_stamp_s(d), _sim_time(d)) for d in client.diagnostics if any(s.name == "boom_sim: drive" for s in d.status)
    ]
    assert len(pairs) >= 4
    # (stamp - simulated time) is the time origin plus how far the ticks trail the clock when the
    # array is made: that lag is up to a /clock period (0.12 s seen throughout a run, against
    # 0 for the array made at the start) plus, on a loaded machine, a few ticks' backlog (0.28 s
    # seen); a pace other than the clock's would drift it by seconds over the phases
    offsets = sorted(stamp - sim for stamp, sim in pairs)
    quarter = len(offsets) // 4
    assert offsets[-1 - quarter] - offsets[quarter] < 0.1, offsets  # the middle half: one lag
    assert offsets[-1] - offsets[0] < 1.0, offsets
    assert "following the ROS clock" in log


def test_a_clock_that_jumps_back_resets_the_drive(nodes, client):
    node = nodes.start("use_sim_time:=true", "command_timeout_s:=0")
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    source = _clock_source("50.0", "1.0:5", "jump:10.0", "1.0:3")
    try:
        assert client.spin_until(lambda: len(client.states) > 5, timeout=20)
        client.spin_until(lambda: client.last().rod_position_m > 1.4, opening=1.0)  # lift: off its initial length
        lifted = client.last()
        assert client.spin_until(lambda: _stamp_s(client.last()) < 20.0, timeout=10), "no state after the jump"
        client.spin_for(0.5)
        after = client.last()
    finally:
        stop_process(source)
        log = stop_process(node)
    assert lifted.rod_position_m > 1.4 and _stamp_s(lifted) > 50.0, log
    assert 10.0 < _stamp_s(after) < 15.0, log
    assert after.rod_position_m == pytest.approx(1.37, abs=2e-3), log  # back at rest, at its initial length
    assert "the ROS clock jumped back" in log


def test_use_sim_time_and_publish_clock_together_are_refused_in_one_line(nodes):
    node = nodes.start("use_sim_time:=true", "publish_clock:=true")
    out, _ = node.communicate(timeout=60)
    assert node.returncode == 2
    assert out.strip().splitlines()[-1].startswith("boom_sim: error: use_sim_time and publish_clock are both true")


def test_a_run_on_the_shared_clock_is_recorded_from_its_first_clock(nodes, client, tmp_path):
    """The bag starts at the first /clock (its time origin), its times are the clock's, and it
    has diagnostics; a command sent before the clock runs is recorded at its start."""
    from bag_checks import check_bag

    from boom_hydraulics.bags.reading import read_custom_data, read_drive_states

    node = nodes.start("use_sim_time:=true", f"record_folder:={tmp_path}", "command_timeout_s:=0", record=True)
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    assert client.spin_until(lambda: client.pub.get_subscription_count() > 0, timeout=10)
    client.spin_for(0.5)
    client.command(0.6)  # before any /clock: it waits for the first step
    client.spin_for(0.3)
    source = _clock_source("200.0", "1.0:3.5")
    try:
        source.communicate(timeout=40)
        # the clock stands at 203.5 s now; a loaded machine may still be working off its backlog
        assert client.spin_until(lambda: client.states and _stamp_s(client.last()) > 203.4, timeout=60)
    finally:
        stop_process(source)
        log = stop_process(node)
    (bag,) = list(tmp_path.iterdir())
    counts = check_bag(bag)
    states = read_drive_states(bag)  # t from the recorded origin: the first /clock the node saw
    origin_s = int(read_custom_data(bag)["clock_origin_ns"]) * 1e-9
    # (a loaded machine catches up with longer ticks: fewer states than 100 per second)
    assert counts["/drive_state"] > 50 and counts["/diagnostics"] >= 1 and counts["/valve_command"] == 1, counts
    assert counts["/robot_description"] == 1
    # the clock source starts once the node has found it: the node's time 0 is its first tick
    assert 200.0 <= origin_s < 201.0 and 0.0 < states["t"][0] < 0.1
    assert 203.4 < origin_s + states["t"][-1] <= 203.5 + 1e-3  # and ran to where the clock stopped
    assert states["u"][0] == 0.6 and states["q1"][-1] > states["q1"][0] + 0.05
    assert "boom_sim: bag" in log


def test_a_reset_on_the_shared_clock_keeps_the_node_on_the_clock(nodes, client):
    """~/reset takes no simulated time: under use_sim_time the node goes on at the clock's
    pace from where it was, its states never stamped ahead of the /clock it follows (it ran
    ahead by the simulated time since the start)."""
    from rosgraph_msgs.msg import Clock

    from boom_hydraulics_msgs.srv import Reset

    clock_s: list[float] = []
    client.node.create_subscription(
        Clock,
        "/clock",
        lambda m: clock_s.append(m.clock.sec + m.clock.nanosec * 1e-9),
        rclpy.qos.qos_profile_sensor_data,  # (the clock source's is best effort)
    )
    node = nodes.start("use_sim_time:=true", "command_timeout_s:=0")
    assert client.spin_until(lambda: client.node.count_publishers("drive_state") > 0, timeout=20)
    source = _clock_source("100.0", "1.0:30")
    try:
        # simulated time far beyond what one tick could hide
        assert client.spin_until(lambda: bool(client.states) and _stamp_s(client.last()) > 102.0, timeout=60)
        assert client.call(client.reset, Reset.Request()).success
        ahead: list[float] = []
        seen = len(client.states)

        def taken() -> bool:
            nonlocal seen
            if not clock_s:  # (this client has yet to find the clock's publisher)
                return False
            ahead.extend(_stamp_s(s) - clock_s[-1] for s in client.states[seen:])
            seen = len(client.states)
            return len(ahead) >= 250  # 2.5 s of the clock

        assert client.spin_until(taken, timeout=60)
    finally:
        stop_process(source)
        log = stop_process(node)
    # a state is stamped with a clock time the node has seen; this client sees the same /clock,
    # a little later or earlier (it takes both topics in turn): well within a tenth of a second
    assert max(ahead) < 0.1, (max(ahead), log)
