"""Bags a running node writes: true to what happened, safe from a kill, never touched while live."""

from __future__ import annotations

import re
import shutil
import signal
import subprocess

import pytest
import yaml
from conftest import BOOM_SIM

rclpy = pytest.importorskip("rclpy")
from bag_checks import check_bag  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

RECOVER = shutil.which("boom-bag-recover")
ANALYZE = shutil.which("boom-analyze")
pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None or RECOVER is None, reason="run through tools/with-env"),
]


def _stop(proc: subprocess.Popen, sig: int = signal.SIGINT) -> str:
    proc.send_signal(sig)
    out, _ = proc.communicate(timeout=20)
    return out


def _offers(info: dict, topic: str) -> list[tuple[str, str]]:
    for entry in info["topics_with_message_count"]:
        if entry["topic_metadata"]["name"] == topic:
            return [(o["reliability"], o["durability"]) for o in entry["topic_metadata"]["offered_qos_profiles"]]
    raise AssertionError(f"{topic} not in the bag's metadata")


@pytest.mark.parametrize("publish_clock", [False, True])
def test_commands_stamped_ahead_behind_or_not_at_all_give_a_true_bag(nodes, client, tmp_path, publish_clock):
    """Log time is when a command was received; its stamp stays inside; QoS is what was offered."""
    params = [f"record_folder:={tmp_path}", "command_timeout_s:=0.0", f"publish_clock:={str(publish_clock).lower()}"]
    proc = nodes.start(*params, record=True)
    array_pub = client.node.create_publisher(
        Float64MultiArray, "commands", QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    try:
        assert client.spin_until(lambda: len(client.states) > 5)
        client.spin_for(0.5)  # discovery both ways
        now = client.last().header.stamp.sec + client.last().header.stamp.nanosec * 1e-9  # the node's clock
        stamps = [now + 30.0, 1.0, None]  # ahead (a scenario sent ahead), long past, unset
        for opening, stamp in zip((0.3, 0.2, 0.1), stamps):
            client.command(opening, stamp_s=stamp)
        array_pub.publish(Float64MultiArray(data=[0.1]))
        client.spin_for(1.5)  # the offers are looked up once a second
    finally:
        out = _stop(proc)
    assert proc.returncode == 0, out
    (bag,) = tmp_path.iterdir()
    counts = check_bag(bag)  # CRC, per-channel log time, metadata times = message times
    assert counts["/valve_command"] == 3 and counts["/commands"] == 1
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["duration"]["nanoseconds"] < 60e9  # not decades
    assert _offers(info, "/valve_command") == [("reliable", "volatile")]  # the test's publisher
    assert _offers(info, "/commands") == [("best_effort", "volatile")]
    with AnyReader([bag]) as reader:
        (commands,) = [c for c in reader.connections if c.topic == "/valve_command"]
        kept = []
        for connection, log_ns, raw in reader.messages(connections=[commands]):
            stamp = reader.deserialize(raw, connection.msgtype).header.stamp
            kept.append((log_ns, stamp.sec + stamp.nanosec * 1e-9))
    assert [round(s, 6) for _, s in kept] == [round(s or 0.0, 6) for s in stamps]  # stamps inside
    assert all(abs(log_ns * 1e-9 - now) < 20.0 for log_ns, _ in kept)  # logged when received


def test_a_live_bag_is_refused_and_a_killed_one_recovered_from_its_first_seconds(nodes, client, tmp_path):
    """Default chunks (1 MiB) fill in minutes; the 1 s flush bound is what keeps data."""
    proc = nodes.start(f"record_folder:={tmp_path}", record=True)
    try:
        assert client.spin_until(lambda: len(client.states) >= 300, timeout=30)  # 3 s of states
        (bag,) = tmp_path.iterdir()
        live = subprocess.run([RECOVER, bag], capture_output=True, text=True, timeout=60)
        assert live.returncode == 1 and "still being recorded" in live.stderr
        assert len(live.stderr.strip().splitlines()) == 1 and "Traceback" not in live.stderr
        assert not list(bag.glob("*.damaged")) and not (bag / "metadata.yaml").exists()
        busy = subprocess.run([ANALYZE, bag, "--out", tmp_path / "a"], capture_output=True, text=True, timeout=60)
        assert busy.returncode == 1 and "still being recorded" in busy.stderr
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    received = len(client.states)
    killed = subprocess.run([ANALYZE, bag, "--out", tmp_path / "a"], capture_output=True, text=True, timeout=60)
    assert killed.returncode == 1 and f"run boom-bag-recover {bag}" in killed.stderr
    assert not (tmp_path / "a").exists()

    result = subprocess.run([RECOVER, bag], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    counts = check_bag(bag)
    # at 100 Hz: no more than the 1 s flush bound (and a little slack for the kill) is lost
    assert counts["/drive_state"] >= max(100, received - 120)

    again = subprocess.run([RECOVER, bag], capture_output=True, text=True, timeout=60)
    assert again.returncode == 1 and "nothing to recover" in again.stderr


def test_help_prints_the_parameters_and_starts_nothing(tmp_path):
    result = subprocess.run([BOOM_SIM, "--help"], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 0
    assert "record_flush_s" in result.stdout and "payload_mass_kg" in result.stdout
    assert re.search(r"^    payload_mass_kg +50\.0 +kg$", result.stdout, re.MULTILINE)  # name, default, unit
    assert "usage: boom_sim" in result.stdout
    assert list(tmp_path.iterdir()) == []  # no bags/ folder, no node


def test_resting_on_an_end_stop_is_normal(nodes, client):
    proc = nodes.start("initial_length_m:=1.05")  # the lower end stop
    try:
        assert client.spin_until(
            lambda: any("at_end_stop" in s.message for d in client.diagnostics for s in d.status), timeout=20
        )
    finally:
        out = _stop(proc)
    # (that stepping starts on time is test_node_stamps': commands act at their stamps)
    resting = next(s for d in client.diagnostics for s in d.status if "at_end_stop" in s.message)
    assert resting.level == b"\x00", out


def test_a_new_time_step_at_run_time_keeps_the_simulation_on_the_clock(nodes, client):
    """The pacing restarts with any parameter change: the step count means another time.
    Simulated time is measured against the diagnostics' stamps (ROS time when they were made)
    over four seconds, so a tick that a loaded machine delays a little changes neither much."""
    proc = nodes.start()
    try:
        assert client.spin_until(lambda: len(client.states) > 50)  # half a second at 1 ms steps
        assert client.set_parameter("time_step_s", 0.002).successful
        client.diagnostics.clear()
        assert client.spin_until(lambda: len(client.diagnostics) >= 6)
    finally:
        out = _stop(proc)
    at = [
        (d.header.stamp.sec + d.header.stamp.nanosec * 1e-9, float(kv.value))
        for d in client.diagnostics[1:]  # the first may have been made before the change
        for s in d.status
        if s.name.endswith("drive")
        for kv in s.values
        if kv.key == "sim_time_s"
    ]
    (ros_a, sim_a), (ros_b, sim_b) = at[0], at[-1]
    assert ros_b - ros_a > 3.0, at
    assert 0.75 < (sim_b - sim_a) / (ros_b - ros_a) < 1.33, at  # a simulated second per second of ROS time
    assert "behind real time" not in out
