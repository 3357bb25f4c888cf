"""``boom-replay``: publish a recorded bag's messages on their topics, as ``ros2 bag play`` does.

    boom-replay bags/20261122-044106_boom_sim
    boom-replay run.mcap --rate 4 --topics /drive_state /joint_states --start 2.5 --loop --clock
    boom-replay run.mcap --wait-for-subscribers       # start once every topic has a subscriber

Messages keep their recorded spacing (divided by ``--rate``); ``--start`` skips the first
seconds; ``--clock`` publishes ``/clock`` with each message's recorded time, so nodes with
``use_sim_time`` follow the bag. For machines without rosbag2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from rosbags.highlevel import AnyReader, AnyReaderError
from rosgraph_msgs.msg import Clock

from .bag_reading import BagError, check_bag_path


def message_class(msgtype: str) -> type:
    """The generated Python class of 'pkg/msg/Type'."""
    package, kind, name = msgtype.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError):
        raise BagError(f"unknown message type {msgtype}; is its package built and sourced?") from None


def _wait_for_subscribers(node, publishers: Sequence, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while any(p.get_subscription_count() == 0 for p in publishers):
        if time.monotonic() > deadline:
            raise BagError(f"no subscriber appeared within {timeout_s:g} s on every replayed topic")
        rclpy.spin_once(node, timeout_sec=0.05)


def replay(
    bag: Path, rate: float, topics: Sequence[str], start_s: float, loop: bool, clock: bool, wait: bool = False
) -> int:
    """Publish the bag's messages; returns how many were published."""
    check_bag_path(bag)
    rclpy.init()
    node = rclpy.create_node("boom_replay")
    published = 0
    try:
        with AnyReader([bag]) as reader:
            connections = [c for c in reader.connections if not topics or c.topic in topics]
            missing = set(topics) - {c.topic for c in connections}
            if missing or not connections:
                found = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
                raise BagError(f"{bag}: no topic {', '.join(sorted(missing)) or 'to replay'}; topics: {found}")
            qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
            publishers = {c.id: node.create_publisher(message_class(c.msgtype), c.topic, qos) for c in connections}
            clock_pub = node.create_publisher(Clock, "/clock", qos) if clock else None
            if wait:
                _wait_for_subscribers(node, list(publishers.values()))
            first = reader.start_time + round(start_s * 1e9)
            while True:
                wall0 = time.monotonic()
                for connection, log_ns, raw in reader.messages(connections=connections, start=first):
                    if not rclpy.ok():  # SIGINT/SIGTERM shut the context down: stop cleanly
                        return published
                    delay = wall0 + (log_ns - first) * 1e-9 / rate - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                    if clock_pub is not None:
                        clock_pub.publish(Clock(clock=Time(nanoseconds=log_ns).to_msg()))
                    publishers[connection.id].publish(bytes(raw))  # CDR as recorded
                    published += 1
                if not loop or not rclpy.ok():
                    break
            time.sleep(0.2)  # let the last messages leave before the node goes
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return published


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="boom-replay", description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="bag folder or .mcap file")
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1)")
    parser.add_argument("--topics", nargs="+", default=[], help="only these topics (default: all)")
    parser.add_argument("--start", type=float, default=0.0, help="skip this many seconds from the start")
    parser.add_argument("--loop", action="store_true", help="play again and again until Ctrl-C")
    parser.add_argument("--clock", action="store_true", help="publish /clock with the recorded times")
    parser.add_argument(
        "--wait-for-subscribers", action="store_true", help="start once every replayed topic has a subscriber"
    )
    args = parser.parse_args(argv)
    if not args.rate > 0 or args.start < 0:
        print("boom-replay: error: --rate must be > 0 and --start >= 0", file=sys.stderr)
        return 2
    try:
        count = replay(args.bag, args.rate, args.topics, args.start, args.loop, args.clock, args.wait_for_subscribers)
    except BagError as exc:
        print(f"boom-replay: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    print(f"boom-replay: published {count} messages from {args.bag}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
