"""A recording killed with SIGKILL is recovered up to its last completed chunk."""

from __future__ import annotations

import shutil
import signal
import subprocess
import time

import pytest
from conftest import BOOM_SIM, start_node

rclpy = pytest.importorskip("rclpy")
from rosbags.highlevel import AnyReader  # noqa: E402

from boom_hydraulics_msgs.msg import DriveState  # noqa: E402

RECOVER = shutil.which("boom-bag-recover")
pytestmark = pytest.mark.skipif(BOOM_SIM is None or RECOVER is None, reason="run through tools/with-env")


def test_sigkill_loses_at_most_the_last_chunk(tmp_path):
    proc = start_node(f"record_folder:={tmp_path}", "record_chunk_kib:=16.0", record=True)
    rclpy.init()
    node = rclpy.create_node("recovery_listener")
    states: list[DriveState] = []
    node.create_subscription(DriveState, "drive_state", states.append, 100)
    try:
        deadline = time.monotonic() + 20
        while len(states) < 300 and time.monotonic() < deadline:  # 3 s of states
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        node.destroy_node()
        rclpy.shutdown()
    (bag,) = list(tmp_path.iterdir())
    assert not (bag / "metadata.yaml").exists()  # killed: never finished
    with pytest.raises(Exception):  # noqa: B017 - whatever the reader raises, it cannot read it
        with AnyReader([next(bag.glob("*.mcap"))]) as reader:
            list(reader.messages())

    result = subprocess.run([RECOVER, bag], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert (bag / "metadata.yaml").is_file() and list(bag.glob("*.mcap.damaged"))
    with AnyReader([bag]) as reader:
        counts: dict[str, int] = {}
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    # 16 KiB chunks hold well under 100 ticks of the six per-tick topics: at most that is lost
    assert counts["/drive_state"] >= len(states) - 100 > 150

    again = subprocess.run([RECOVER, bag], capture_output=True, text=True, timeout=60)
    assert again.returncode == 1 and "nothing to recover" in again.stderr
