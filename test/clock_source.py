"""A separate process that publishes /clock, as a simulator such as Gazebo does.

    python clock_source.py START_S FACTOR:WALL_S [FACTOR:WALL_S ...] [jump:TO_S ...]

Waits until a subscriber has matched /clock, then publishes at 200 Hz of wall time from
START_S: each FACTOR:WALL_S phase advances the clock FACTOR simulated seconds per wall
second for WALL_S wall seconds (0: paused, still publishing); jump:TO_S sets the clock to
TO_S. Prints each phase's start time and exits.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock


def main() -> None:
    clock_s = float(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node("clock_source")
    pub = node.create_publisher(Clock, "/clock", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    period = 1.0 / 200.0
    deadline = time.monotonic() + 20.0  # the clock starts once a subscriber has found it (DDS discovery)
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    for phase in sys.argv[2:]:
        kind, _, value = phase.partition(":")
        if kind == "jump":
            clock_s = float(value)
            print(f"jump {clock_s:.6f}", flush=True)
            continue
        factor, wall_s = float(kind), float(value)
        print(f"phase {factor} from {clock_s:.6f}", flush=True)
        end = time.monotonic() + wall_s
        last = time.monotonic()
        while (now := time.monotonic()) < end:
            clock_s += factor * (now - last)
            last = now
            msg = Clock()
            msg.clock.sec = int(clock_s)
            msg.clock.nanosec = int((clock_s - int(clock_s)) * 1e9)
            pub.publish(msg)
            time.sleep(period)
    print(f"end {clock_s:.6f}", flush=True)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
