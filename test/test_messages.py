"""The generated interfaces: import, CDR round-trip, and delivery between two processes."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

rclpy = pytest.importorskip("rclpy")
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from boom_hydraulics_msgs.msg import DriveState, ValveCommand  # noqa: E402
from boom_hydraulics_msgs.srv import Reset, Step  # noqa: E402


def test_drive_state_round_trips_through_cdr():
    msg = DriveState()
    msg.header.frame_id = "boom_base"
    msg.header.stamp.sec = 12
    msg.rod_position_m = 1.4321
    msg.piston_pressure_pa = 3.87e6
    msg.supply_energy_j = 1234.5
    msg.cavitation = True
    data = serialize_message(msg)
    back = deserialize_message(data, DriveState)
    assert back == msg
    assert back.rod_position_m == 1.4321 and back.cavitation is True


def test_valve_command_and_services_round_trip():
    cmd = ValveCommand(opening=-0.75)
    assert deserialize_message(serialize_message(cmd), ValveCommand).opening == -0.75
    req = Reset.Request(use_rod_position=True, rod_position_m=1.5)
    assert deserialize_message(serialize_message(req), Reset.Request) == req
    res = Step.Response(success=True, message="ok", sim_time_s=0.25)
    assert deserialize_message(serialize_message(res), Step.Response) == res


PUBLISHER = textwrap.dedent(
    """
    import time, rclpy
    from boom_hydraulics_msgs.msg import ValveCommand
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    pub = node.create_publisher(ValveCommand, "valve_command", 10)
    end = time.monotonic() + 20.0
    i = 0
    while time.monotonic() < end:
        pub.publish(ValveCommand(opening=0.25 + i * 1e-3))
        i += 1
        rclpy.spin_once(node, timeout_sec=0.05)
    """
)


def test_message_crosses_process_boundary():
    """A ValveCommand published by another process arrives here intact."""
    proc = subprocess.Popen([sys.executable, "-c", PUBLISHER])
    rclpy.init()
    node = rclpy.create_node("test_subscriber")
    received: list[float] = []
    node.create_subscription(ValveCommand, "valve_command", lambda m: received.append(m.opening), 10)
    try:
        deadline = time.monotonic() + 15.0
        while len(received) < 3 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.shutdown()
        proc.kill()
        proc.wait()
    assert len(received) >= 3, "no message from the publisher process within 15 s"
    assert all(0.25 <= u < 0.3 for u in received)
