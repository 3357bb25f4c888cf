"""boom-replay publishes a bag's messages on their topics, in order and with their spacing."""

from __future__ import annotations

import shutil
import subprocess
import time

import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402

from boom_hydraulics.recording import BagRecorder, Topic  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402

BOOM_REPLAY = shutil.which("boom-replay")
pytestmark = pytest.mark.skipif(BOOM_REPLAY is None, reason="boom-replay not on PATH")


def _bag(folder):
    topics = [
        Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState"),
        Topic("/valve_command", "boom_hydraulics_msgs/msg/ValveCommand"),
    ]
    with BagRecorder(folder, topics) as rec:
        for i in range(60):  # 0.59 s of states, 10 ms apart
            msg = DriveState(rod_position_m=1.3 + i * 1e-3)
            msg.header.stamp.nanosec = i * 10_000_000
            rec.write("/drive_state", i * 10_000_000, serialize_message(msg))
        rec.write("/valve_command", 5_000_000, serialize_message(ValveCommand(opening=0.5)))


def test_replay_publishes_every_message_in_order_with_its_spacing(tmp_path):
    _bag(tmp_path / "run")
    rclpy.init()
    node = rclpy.create_node("replay_listener")
    received: list[tuple[float, float]] = []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(
        DriveState, "/drive_state", lambda m: received.append((time.monotonic(), m.rod_position_m)), qos
    )
    proc = subprocess.Popen(
        [BOOM_REPLAY, tmp_path / "run", "--topics", "/drive_state", "--rate", "0.5", "--wait-for-subscribers"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
        for _ in range(20):
            rclpy.spin_once(node, timeout_sec=0.02)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "published 60 messages" in out
    assert [round(q, 6) for _, q in received] == [round(1.3 + i * 1e-3, 6) for i in range(60)]
    # 0.59 s of recording at rate 0.5 takes at least 1.18 s (a lower bound: load only adds time)
    assert received[-1][0] - received[0][0] >= 0.9 * 1.18


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nope"], "no such bag folder or file"),
        (["BAG", "--topics", "/missing"], "no topic /missing"),
    ],
)
def test_replay_errors_are_one_line(tmp_path, args, message):
    _bag(tmp_path / "run")
    args = [str(tmp_path / "run") if a == "BAG" else str(tmp_path / a) if a == "nope" else a for a in args]
    result = subprocess.run([BOOM_REPLAY, *args], capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
