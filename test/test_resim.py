"""boom-resim: a recorded node run fed through the model again, unchanged and "what if"."""

from __future__ import annotations

import shutil
import signal
import subprocess
import time

import numpy as np
import pytest
from conftest import BOOM_SIM, start_node

rclpy = pytest.importorskip("rclpy")
from std_srvs.srv import SetBool  # noqa: E402

from boom_hydraulics.bag_reading import read_drive_states  # noqa: E402
from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402

BOOM_RESIM = shutil.which("boom-resim")
pytestmark = pytest.mark.skipif(BOOM_SIM is None or BOOM_RESIM is None, reason="run through tools/with-env")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A node run with /clock: lift, hold, lower, queued while paused, then as fast as possible."""
    folder = tmp_path_factory.mktemp("bags")
    proc = start_node(
        "publish_clock:=true", "real_time_factor:=0.0", "start_paused:=true", f"record_folder:={folder}", record=True
    )
    rclpy.init()
    node = rclpy.create_node("resim_driver")
    states: list[DriveState] = []
    node.create_subscription(DriveState, "drive_state", states.append, 10)
    pub = node.create_publisher(ValveCommand, "valve_command", 10)
    pause = node.create_client(SetBool, "/boom_sim/pause")
    try:
        assert pause.wait_for_service(timeout_sec=20)
        deadline = time.monotonic() + 10
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
        end = time.monotonic() + 1.0  # let discovery settle both ways (best-effort reader)
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        for _ in range(2):  # twice: a stamped duplicate applies at the same time, in node and resim alike
            for at, opening in [(0.5, 1.0), (2.0, 0.0), (2.5, -0.8), (3.5, 0.0)]:
                msg = ValveCommand(opening=opening)
                msg.header.stamp.sec, msg.header.stamp.nanosec = int(at), round((at - int(at)) * 1e9)
                pub.publish(msg)
        for _ in range(10):
            rclpy.spin_once(node, timeout_sec=0.05)
        future = pause.call_async(SetBool.Request(data=False))
        deadline = time.monotonic() + 30
        while not (states and states[-1].header.stamp.sec >= 4) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.02)
        assert future.done()
    finally:
        node.destroy_node()
        rclpy.shutdown()
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)
    (bag,) = list(folder.iterdir())
    return bag


def test_unchanged_resimulation_reproduces_the_recorded_run(recorded, tmp_path):
    result = subprocess.run([BOOM_RESIM, recorded, "--out", tmp_path / "same"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    original, again = read_drive_states(recorded), read_drive_states(tmp_path / "same")
    # it lifted and lowered (each for 0.5 s: the node's command timeout closes the valve)
    assert original["q1"].max() > original["q1"][0] + 0.05
    assert original["q1"][-1] < original["q1"].max() - 0.05
    n = min(len(original["q1"]), len(again["q1"]))
    assert n > 300
    assert np.max(np.abs(original["q1"][:n] - again["q1"][:n])) < 1e-12
    assert np.max(np.abs(original["p1"][:n] - again["p1"][:n])) < 1e-6


def test_what_if_a_heavier_payload(recorded, tmp_path):
    out = tmp_path / "heavy"
    result = subprocess.run(
        [BOOM_RESIM, recorded, "--set", "payload_mass_kg=250", "--out", out], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    original, heavy = read_drive_states(recorded), read_drive_states(out)
    lift = lambda s: s["q1"].max() - s["q1"][0]  # noqa: E731
    assert lift(heavy) < lift(original)  # same commands, slower lift
    assert heavy["p1"].max() > original["p1"][: len(heavy["p1"])].max() - 1.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--set", "rod_diameter_m=0.05"], "must be smaller than piston_diameter_m"),
        (["--set", "nonsense=1"], "unknown parameter 'nonsense'"),
    ],
)
def test_bad_changes_are_refused_and_nothing_is_written(recorded, tmp_path, args, message):
    out = tmp_path / "never"
    result = subprocess.run([BOOM_RESIM, recorded, *args, "--out", out], capture_output=True, text=True)
    assert result.returncode == 1 and message in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()
