"""The boom_sim node in its own process, driven from this one with rclpy."""

from __future__ import annotations

import itertools
import math
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import yaml
from conftest import BOOM_SIM, CONFIG, GUARD_S, stop_process

rclpy = pytest.importorskip("rclpy")
from rcl_interfaces.srv import GetParameters  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics.model import config  # noqa: E402
from boom_hydraulics.solve.commands import steps  # noqa: E402
from boom_hydraulics.solve.simulation import simulate  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState  # noqa: E402
from boom_hydraulics_msgs.srv import Reset, Step  # noqa: E402

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]


class TestOneRunningNode:
    """Tests that drive one node (conftest.shared_node), each finding it at rest with its start
    parameters (conftest.node_at_rest), as if it had just started it. The node is stopped with
    SIGTERM after the last of them and must end with status 0."""

    def test_openings_hold_extend_and_retract(self, node_at_rest, client):
        q0, alpha0 = client.last().rod_position_m, client.last().boom_angle_rad
        client.spin_sim(1.0, opening=0.0)  # closed valve from rest: only leakage moves the rod
        assert abs(client.last().rod_position_m - q0) < 5e-4
        assert client.acting_on(1.0)
        client.spin_sim(1.0, opening=1.0)
        up = client.last()
        assert up.rod_position_m > q0 + 0.05 and up.boom_angle_rad > alpha0 + 0.1
        assert client.acting_on(-1.0)
        client.spin_sim(1.0, opening=-1.0)
        down = client.last()
        assert down.rod_position_m < up.rod_position_m - 0.05
        assert client.joints and client.joints[-1].name == ["boom_joint", "cylinder_barrel_joint", "cylinder_joint"]
        # the FluidPressure of a tick carries the same value and stamp as that tick's DriveState
        by_stamp = {(s.header.stamp.sec, s.header.stamp.nanosec): s.piston_pressure_pa for s in client.states}
        matched = [
            (m.fluid_pressure, by_stamp[key])
            for m in client.pressures
            if (key := (m.header.stamp.sec, m.header.stamp.nanosec)) in by_stamp
        ]
        assert len(matched) > 10 and all(a == b for a, b in matched)

    def test_nan_is_ignored_and_the_valve_closes_after_the_timeout(self, node_at_rest, client):
        assert client.acting_on(0.8)
        client.spin_sim(0.3, opening=math.nan)  # ignored: 0.8 stays, inside the 0.5 s timeout
        assert client.last().valve_command == pytest.approx(0.8)
        assert client.last().rod_velocity_m_s > 0.02
        client.spin_sim(1.0)  # no commands: the spring-centred valve closes
        assert client.last().valve_command == 0.0
        assert node_at_rest.poll() is None  # still running

    def test_out_of_range_opening_is_clamped(self, node_at_rest, client):
        assert client.acting_on(7.0, valve_command=1.0)
        assert max(s.valve_command for s in client.states) == 1.0

    def test_bad_parameter_is_refused_with_a_reason_and_a_good_one_applies(self, node_at_rest, client):
        bad = client.set_parameter("rod_diameter_m", 0.05)
        assert not bad.successful and "must be smaller than piston_diameter_m" in bad.reason
        got = client.call(client.get_params, GetParameters.Request(names=["rod_diameter_m"]))
        assert got.values[0].double_value == 0.022  # the old value stays

        assert client.call(client.pause, SetBool.Request(data=True)).success
        p_light = _reset_while_paused(client).piston_pressure_pa
        assert client.set_parameter("payload_mass_kg", 150.0).successful
        heavy = _reset_while_paused(client).piston_pressure_pa
        assert heavy > 1.5 * p_light  # heavier payload, higher holding pressure

    def test_an_external_rod_force_set_at_run_time_is_carried_and_nan_is_refused(self, node_at_rest, client):
        """Pushing the rod out with F_ext while the closed valve holds the boom: the oil gives
        up that much of its force p1 S1 - p2 S2 (the spool's leakage moves p1 and p2 meanwhile,
        their force balance stays), and held at rest after a reset, the piston chamber holds the
        boom at exactly F_ext / S1 less pressure (eq. 11 at rest)."""
        force_n, s1 = 2000.0, math.pi * 0.04**2 / 4  # the boom's static load is 4.9 kN
        nan = client.set_parameter("external_rod_force_n", math.nan)
        assert not nan.successful and "external_rod_force_n" in nan.reason and "nan" in nan.reason  # rclpy's range
        assert "\n" not in nan.reason
        assert client.spin_until(lambda: len(client.states) > 0)
        f_held = client.last().hydraulic_force_n
        assert client.set_parameter("external_rod_force_n", force_n).successful
        assert client.spin_until(lambda: client.last().hydraulic_force_n < f_held - 0.5 * force_n)

        assert client.call(client.pause, SetBool.Request(data=True)).success
        pushed = _reset_while_paused(client).piston_pressure_pa
        assert client.set_parameter("external_rod_force_n", 0.0).successful
        free = _reset_while_paused(client).piston_pressure_pa
        assert free - pushed == pytest.approx(force_n / s1, rel=1e-6)

    def test_reset_pause_and_step(self, node_at_rest, client):
        result = client.call(client.reset, Reset.Request(use_rod_position=True, rod_position_m=1.6))
        assert result.success
        assert client.spin_until(lambda: abs(client.last().rod_position_m - 1.6) < 1e-3)
        bad = client.call(client.reset, Reset.Request(use_rod_position=True, rod_position_m=1.9))
        assert not bad.success and "outside the stroke" in bad.message
        assert client.call(client.step, Step.Request(steps=5)).success is False  # not paused
        assert client.call(client.pause, SetBool.Request(data=True)).success
        first = client.call(client.step, Step.Request(steps=10))
        second = client.call(client.step, Step.Request(steps=10))
        assert first.success and second.sim_time_s == pytest.approx(first.sim_time_s + 0.010, abs=1e-9)
        client.spin_for(0.3)
        third = client.call(client.step, Step.Request(steps=1))
        assert third.sim_time_s == pytest.approx(second.sim_time_s + 0.001, abs=1e-9)  # paused: time stood still
        assert client.call(client.pause, SetBool.Request(data=False)).success

    def test_diagnostics_report_the_end_stop(self, node_at_rest, client):
        assert client.spin_until(lambda: client.last().at_end_stop, opening=1.0)  # the upper stop, about 2 s away
        assert client.spin_until(  # diagnostics come at 1 Hz
            lambda: any("at_end_stop" in s.message for d in client.diagnostics for s in d.status), opening=1.0
        )

    def test_command_timeout_changed_at_run_time_takes_effect(self, node_at_rest, client):
        assert client.set_parameter("command_timeout_s", 0.0).successful  # never close by itself
        assert client.acting_on(0.6)
        client.spin_sim(1.0)  # no commands for twice the start value of 0.5 s
        assert client.last().valve_command == pytest.approx(0.6)


def test_fast_run_with_clock_equals_the_headless_simulation(nodes, client):
    """Real-time factor 0 (as fast as possible), /clock, a stamped scenario queued while paused."""
    proc = nodes.start("real_time_factor:=0.0", "publish_clock:=true", "start_paused:=true", "command_timeout_s:=0.0")
    try:
        scenario = [(0.0, 1.0), (3.0, 0.0), (5.0, -0.7), (8.0, 0.0)]
        assert client.pause.wait_for_service(timeout_sec=15)
        # the node takes commands best-effort: send them once its subscription is matched
        assert client.spin_until(lambda: client.pub.get_subscription_count() > 0)
        client.spin_for(0.5)
        for at, opening in scenario:
            client.command(opening, stamp_s=at if at > 0 else None)
        client.spin_for(0.5)
        start = time.monotonic()
        client.call(client.pause, SetBool.Request(data=False))
        assert client.spin_until(lambda: client.states and client.last().header.stamp.sec >= 10, timeout=60)
        wall = time.monotonic() - start
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
    # faster than real time: it does not wait for the wall clock (about 1.5 s unloaded, 5.5 s
    # with four CPU hogs on two cores, measured); speed itself is bench/bench_node.py's job
    assert wall < 10.0
    stamps = np.array([s.header.stamp.sec + s.header.stamp.nanosec * 1e-9 for s in client.states])
    q_node = np.array([s.rod_position_m for s in client.states])
    params = config.load(CONFIG / "default.yaml")
    headless = simulate(params, 10.0, steps([t for t, _ in scenario], [u for _, u in scenario]), jit=False)
    index = np.round(stamps / params.time_step_s).astype(int)
    keep = index <= 10_000
    # as fast as possible, a loaded subscriber takes some of the states only (52 of 1000 on a
    # clean clone's make test with the other core busy): the ones it took cover every part of
    # the scenario, and each equals the headless run at its stamp
    starts = [t for t, _ in scenario]
    assert all(((stamps >= a) & (stamps < b)).any() for a, b in zip(starts, [*starts[1:], 10.0])), stamps
    assert np.max(np.abs(q_node[keep] - headless["q1"][index[keep]])) < 1e-12


def test_a_blow_up_stops_the_simulation_until_reset(nodes, client):
    """Paper mode has no end stops: fig. 8 leaves the valid geometry after 2.2 s."""
    proc = nodes.start("real_time_factor:=4.0", "command_timeout_s:=0.0", config_file="paper_fig8.yaml")
    try:
        assert client.spin_until(lambda: len(client.states) > 3)
        client.command(1.0)
        assert client.spin_until(
            lambda: any(s.level == b"\x02" and "stopped" in s.message for d in client.diagnostics for s in d.status),
            timeout=10,
        )
        assert all(math.isfinite(s.rod_position_m) and s.rod_position_m < 1.8 for s in client.states)
        count = len(client.states)
        client.spin_for(0.5)
        # no more state while stopped: states still in flight when the stop was reported may
        # come after it, each further along (the open valve draws energy at every step); one
        # published while stopped would repeat the stopped state
        energies = [s.supply_energy_j for s in client.states[count - 1 :]]
        assert all(b > a for a, b in itertools.pairwise(energies)), energies
        count = len(client.states)
        assert client.call(client.reset, Reset.Request()).success
        assert client.spin_until(lambda: len(client.states) > count + 3)
        assert client.last().rod_position_m == pytest.approx(1.37, abs=0.01)
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0


def test_stiff_settings_are_substepped_and_the_node_says_so(nodes, client):
    """1.6 GPa oil with 10 cm3 hoses: the node keeps its 1 ms step, takes the substeps the
    stability bound asks for, logs it once and reports it in /diagnostics."""
    proc = nodes.start(
        "bulk_modulus_pa:=1.6e9", "piston_dead_volume_m3:=1e-5", "rod_dead_volume_m3:=1e-5", "command_timeout_s:=0.0"
    )
    try:
        assert client.spin_until(lambda: len(client.states) > 3)
        client.command(-1.0)  # lower onto the stop: the piston chamber shrinks to its dead volume

        def substeps() -> int:
            values = [v for d in client.diagnostics for s in d.status for v in s.values if v.key == "substeps_most"]
            return int(values[-1].value) if values else 0

        assert client.spin_until(lambda: substeps() > 1, timeout=20)
        # (the states that came with the diagnostics may be a tick behind them: wait for the one)
        assert client.spin_until(lambda: client.last().rod_position_m < 1.2, timeout=20)
        assert not any(s.level == b"\x02" for d in client.diagnostics for s in d.status)  # still running
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=10)
    assert proc.returncode == 0
    assert "stability bound: rk4 takes" in out and "substeps per time step of 0.001 s" in out


def test_a_node_started_with_a_small_fixed_pump_lifts_at_the_pumps_flow(nodes, client):
    """drive:=fixed_pump (start-only): the valve fully open, the boom rises as fast as the pump's
    delivered flow fills the piston chamber (eq. D1), the relief shut below p_n."""
    from boom_hydraulics.model.drives import constants as drive_constants
    from boom_hydraulics.model.parameters import from_mapping
    from boom_hydraulics.model.physical import constants

    proc = nodes.start("drive:=fixed_pump", "pump_max_flow_m3_s:=2.0e-4", "command_timeout_s:=0.0")
    try:
        client.handshake()  # discovery done both ways: the command below reaches the node
        start = client.last().rod_position_m
        client.command(1.0)
        # the line and the boom ring for the first few centimetres; from 10 to 15 cm the lift is steady
        assert client.spin_until(lambda: client.last().rod_position_m > start + 0.15)
        steady = [s for s in client.states if start + 0.10 <= s.rod_position_m <= start + 0.15]
        first, last = steady[0], steady[-1]
        seconds = (last.header.stamp.sec - first.header.stamp.sec) + (
            last.header.stamp.nanosec - first.header.stamp.nanosec
        ) * 1e-9
        velocity = (last.rod_position_m - first.rod_position_m) / seconds
    finally:
        out = stop_process(proc)
    p = from_mapping({"pump_max_flow_m3_s": 2.0e-4, "drive": "fixed_pump"})
    d = drive_constants(p)
    # the line below p_n: at most the pump's geometric flow, at least what it delivers at p_n
    most = d.displacement * d.speed / constants(p).s1
    least = (d.displacement * d.speed - d.pump_leak * (p.supply_pressure_pa - p.tank_pressure_pa)) / constants(p).s1
    assert least * 0.99 < velocity < most, (least, velocity, most)
    assert ", drive fixed_pump" in out


def test_a_broken_energy_balance_stops_the_node_and_is_reported(nodes, client):
    """Euler at 3 substeps cannot hold the hydraulic oscillation of a lift: the guard stops
    the simulation and /diagnostics says why, naming the step."""
    proc = nodes.start("method:=euler", "substeps:=3", "spool_time_constant_s:=0.0", "command_timeout_s:=0.0")
    try:
        client.handshake()
        # stamped on the node's clock (the system clock), so that they act at these instants
        # however late a loaded machine delivers them: lift, and 0.6 s later close the valve
        # on the moving boom, which rings the oil springs
        opened_s = time.time() + 0.5
        client.command(1.0, stamp_s=opened_s)
        client.command(0.0, stamp_s=opened_s + 0.6)

        def stopped() -> list[str]:
            return [s.message for d in client.diagnostics for s in d.status if s.level == b"\x02"]

        assert client.spin_until(lambda: bool(stopped()))
        assert "energy balance broken" in stopped()[-1] and "step of 0.001 s (euler" in stopped()[-1]
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0


#: A process of its own (rclpy refuses two types on one topic in one process): publishers
#: whose messages cannot reach boom_sim, and one that can, until it is stopped.
_UNREACHABLE_PUBLISHERS = """
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory
rclpy.init()
node = rclpy.create_node("unreachable_publishers")
best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
node.create_publisher(String, "valve_command", best_effort)
node.create_publisher(JointTrajectory, "boom_sim/joint_trajectory", best_effort)
good = rclpy.create_node("good_publisher")
good.create_publisher(JointTrajectory, "boom_sim/joint_trajectory", QoSProfile(depth=10))  # (reliable)
print("publishing", flush=True)
rclpy.spin(node)
"""


def test_a_publisher_whose_messages_cannot_arrive_is_named_in_one_warning(nodes, client, tmp_path):
    """Another type on valve_command, best effort on the reliable ~/joint_trajectory: the node
    says so once per publisher, naming it and the topic (in place of rclpy's default event
    handlers, which the node leaves out); publishers that reach it are not mentioned. The
    bag's valve_command lists the offer of the test's publisher alone (reliable), not that
    of the best-effort String publisher."""
    proc = nodes.start(f"record_folder:={tmp_path}", record=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)  # (line by line)
    reader.start()
    publishers = subprocess.Popen(
        [sys.executable, "-c", _UNREACHABLE_PUBLISHERS], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        ready = threading.Event()
        first: list[str] = []
        threading.Thread(target=lambda: (first.append(publishers.stdout.readline()), ready.set()), daemon=True).start()
        assert ready.wait(GUARD_S) and first == ["publishing\n"], stop_process(publishers)
        wrong_type = "publisher /unreachable_publishers sends std_msgs/msg/String on /valve_command"
        wrong_qos = "publisher /unreachable_publishers on /boom_sim/joint_trajectory offers QoS"
        told = lambda: all(any(want in line for line in lines) for want in (wrong_type, wrong_qos))  # noqa: E731
        assert client.spin_until(lambda: told() or proc.poll() is not None) and told(), "".join(lines)
        seen = len(client.diagnostics)  # the node looks once a second, then publishes /diagnostics:
        assert client.spin_until(lambda: len(client.diagnostics) >= seen + 2)  # it looked again since
    finally:
        stop_process(publishers)
    proc.send_signal(signal.SIGINT)
    reader.join(timeout=GUARD_S)
    out = "".join(lines)
    assert "where this node takes boom_hydraulics_msgs/msg/ValveCommand" in out, out
    assert "(best effort publisher and reliable subscription)" in out, out
    assert "publish with --qos-reliability reliable" in out, out
    warnings = [line for line in lines if "none of its messages arrive" in line]
    assert len(warnings) == 2, out  # once each; not the good publisher, nor the test's client
    assert proc.wait(timeout=GUARD_S) == 0, out
    (bag,) = tmp_path.iterdir()
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (valve,) = [
        t["topic_metadata"]
        for t in info["topics_with_message_count"]
        if t["topic_metadata"]["name"] == "/valve_command"
    ]
    assert [o["reliability"] for o in valve["offered_qos_profiles"]] == ["reliable"], valve


def test_bad_node_parameter_at_start_is_one_clear_line(nodes):
    proc = nodes.start("real_time_factor:=-2.0")
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert "boom_sim: error:" in out and "real_time_factor" in out and "-2.0" in out
    assert "Traceback" not in out


def test_bad_model_parameter_at_start_is_one_clear_line(nodes):
    proc = nodes.start("rod_diameter_m:=0.05")
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert "boom_sim: error: rod_diameter_m (0.05 m) must be smaller than piston_diameter_m" in out
    assert "Traceback" not in out


def _reset_while_paused(client) -> DriveState:
    """~/reset of a paused node: the one state it publishes, at rest, its energy counters at zero
    (a loaded machine may still hand this client states of before the pause, which have drawn
    energy since the last reset)."""
    client.states.clear()
    assert client.call(client.reset, Reset.Request()).success
    assert client.spin_until(lambda: any(s.supply_energy_j == 0.0 for s in client.states))
    return next(s for s in reversed(client.states) if s.supply_energy_j == 0.0)


def test_a_second_ctrl_c_while_the_finished_node_shuts_down_changes_nothing(nodes, client, tmp_path):
    """Ctrl-C, then Ctrl-C again once the bag's line is out (a double press): exit status 0 and
    nothing more printed. Python's shutdown, half a second after that line, had put back the
    default action of SIGINT, and the second press killed the process (status 130)."""
    proc = nodes.start(f"record_folder:={tmp_path}", record=True)
    assert client.spin_until(lambda: len(client.states) > 10)  # it runs and records
    proc.send_signal(signal.SIGINT)
    assert proc.stdout is not None
    said = []
    for line in proc.stdout:  # (ends when the process does: then the test fails below)
        said.append(line)
        if line.startswith("boom_sim: bag "):
            break
    time.sleep(0.1)  # (not a wait: the press lands in the shutdown's half second, which follows the line)
    proc.send_signal(signal.SIGINT)  # while the finished node shuts down
    said.append(proc.stdout.read())
    proc.wait(timeout=30)
    out = "".join(said)
    assert proc.returncode == 0, out
    assert "boom_sim: bag " in out and "Traceback" not in out, out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_recording_holds_every_published_and_received_message(nodes, client, tmp_path, sig):
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    proc = nodes.start("command_timeout_s:=0.0", f"record_folder:={tmp_path}", record=True)
    client.handshake()  # the node takes this client's commands (discovery done both ways)
    sent = [0.5 + 0.001 * k for k in range(20)]
    for opening in sent:
        client.command(opening)
        client.spin_for(0.05)
    assert client.spin_until(lambda: client.last().valve_command == sent[-1])
    # the node had taken every command by now (it published a state that shows the last one):
    # its count of them is in a diagnostics array stamped (system clock) after now; one made
    # earlier can still arrive after that state on a loaded machine
    seen_ns = time.time_ns()

    def counted_after() -> dict[str, str]:
        for array in client.diagnostics:
            if array.header.stamp.sec * 10**9 + array.header.stamp.nanosec >= seen_ns:
                for status in array.status:
                    if status.name.endswith("commands"):
                        return {kv.key: kv.value for kv in status.values}
        return {}

    assert client.spin_until(lambda: "received" in counted_after())
    received = int(counted_after()["received"])
    ticks = len(client.states)
    assert client.spin_until(lambda: len(client.states) > ticks + 100)  # a second of ticks more
    proc.send_signal(sig)  # either signal finishes the bag
    out, _ = proc.communicate(timeout=20)
    assert proc.returncode == 0
    (folder,) = list(tmp_path.iterdir())
    assert f"boom_sim: bag {folder}" in out
    assert (folder / "metadata.yaml").is_file()

    with AnyReader([folder]) as reader:
        counts: dict[str, int] = {}
        openings: list[float] = []
        for connection, timestamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)  # every message deserialises
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == "/valve_command":
                openings.append(msg.opening)
            if connection.topic == "/drive_state":  # logged when published, stamped with its instant
                stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                assert stamp - 1_000_000 <= timestamp, (stamp, timestamp)
    per_tick = {
        counts[t]
        for t in ("/drive_state", "/joint_states", "/piston_pressure", "/rod_pressure", "/rod_force", "/hinge_wrench")
    }
    assert len(per_tick) == 1 and per_tick.pop() > 100
    # every command the node received, once, in order: a best-effort subscription (sensor data
    # QoS) may lose some on a loaded machine before the node takes them, never after
    assert len(openings) == received and openings[-1] == sent[-1]
    ours = [o for o in openings if o >= 0.5]
    assert ours == sorted(set(ours)) and set(ours) <= set(sent)
    assert counts["/diagnostics"] >= 1

    with (folder / f"{folder.name}_0.mcap").open("rb") as handle:
        reader = make_reader(handle)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary.statistics.message_count == sum(counts.values())
        assert all(s.encoding == "ros2msg" for s in summary.schemas.values())
        drive = next(s for s in summary.schemas.values() if s.name == "boom_hydraulics_msgs/msg/DriveState")
        assert b"MSG: std_msgs/Header" in drive.data and b"MSG: builtin_interfaces/Time" in drive.data
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
            assert "reliability:" in channel.metadata["offered_qos_profiles"]
        assert summary.chunk_indexes and all(c.compression == "zstd" for c in summary.chunk_indexes)


@pytest.mark.parametrize("presses", [1, 2], ids=["ctrl-c", "ctrl-c-twice"])
def test_ctrl_c_while_the_node_compiles_ends_it_in_one_line_with_nothing_recorded(client, tmp_path, presses):
    """A first start (an empty compile cache) stopped from the terminal while it compiles: exit
    status 0, the one line that says so, no traceback, no bag folder."""
    import os
    import subprocess

    env = {**os.environ, "BOOM_HYDRAULICS_CACHE": str(tmp_path / "cache")}  # nothing compiled: it compiles
    bags = tmp_path / "bags"
    proc = subprocess.Popen(
        [BOOM_SIM, "--ros-args", "--params-file", str(CONFIG / "default.yaml"), "-p", f"record_folder:={bags}"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
    )  # fmt: skip
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)  # (line by line)
    reader.start()
    try:
        # with an empty cache the node says it compiles (tens of seconds; its first log line
        # comes after), once its parameters are declared
        said = client.spin_until(lambda: any("model's rk4 is not compiled on this machine" in ln for ln in lines), 60)
        assert said, "".join(lines)
        for _ in range(presses):
            proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        reader.join(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    out = "".join(lines)
    assert proc.returncode == 0, out
    assert "Traceback" not in out and "recording to" not in out, out
    assert "physical mode," not in out, out  # (its first log line, once compiled: it was stopped before)
    said, stopped = out.strip().splitlines()
    assert said.endswith(
        "the physical model's rk4 is not compiled on this machine yet: compiling it for this start takes tens of "
        "seconds, minutes on a busy machine (once: later runs load it)"
    ), out
    assert stopped == "boom_sim: stopped while starting; nothing was recorded", out
    assert not bags.exists()


def test_a_ctrl_c_that_python_drops_while_the_node_starts_ends_it_in_one_line(tmp_path):
    """Python drops a KeyboardInterrupt raised in a finalizer or a ctypes callback (a Ctrl-C
    that lands in llvmlite's cache callback while the node compiles): no 'Exception ignored'
    traceback, and the node still stops, in its one line, with nothing recorded."""
    import subprocess
    import sys

    script = f"""
import os, signal, sys, time
import rclpy
from boom_hydraulics.ros import node, process

class Dropped:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):  # the handler runs here, inside the finalizer: its exception is dropped
            pass
        print("not dropped: the interrupt did not come inside the finalizer")  # (fails the test)

start = node.BoomSimNode.__init__

def starting(self):
    Dropped()
    deadline = time.monotonic() + 60
    while rclpy.ok() and time.monotonic() < deadline:  # the signal shuts the context down, just after
        time.sleep(0.01)
    start(self)

node.BoomSimNode.__init__ = starting
process.main(["boom_sim", "--ros-args", "--params-file", {str(CONFIG / "default.yaml")!r},
              "-p", "record_folder:={tmp_path / "bags"}"])
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    out = done.stdout + done.stderr
    assert done.returncode == 0, out
    assert "Exception ignored" not in out and "Traceback" not in out, out
    assert out.strip().splitlines() == ["boom_sim: stopped while starting; nothing was recorded"], out
    assert not (tmp_path / "bags").exists()
