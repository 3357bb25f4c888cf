"""``boom-replay``: publish a recorded bag's messages on their topics, as ``ros2 bag play`` does.

    boom-replay bags/20261122-044106_boom_sim
    boom-replay run.mcap --rate 4 --topics /drive_state /joint_states --start 2.5 --loop --clock
    boom-replay run.mcap --wait-for-subscribers --wait-timeout 60
    boom-replay run.mcap --no-wait

Messages keep their recorded spacing (divided by --rate); --start skips the first
seconds. Each topic is offered the QoS its recorded publishers offered (as ros2 bag play
does: their common profile, or reliable and volatile where they differed). --clock
publishes /clock with each message's recorded time, so nodes with use_sim_time follow the
bag; a bag that holds /clock itself is replayed with its own /clock only.
By default it starts once every topic that has messages to replay has a subscriber, or
after --wait-timeout seconds with a note naming the topics nobody subscribed to: DDS
discovery takes a second or two, and messages published before it would be lost.
--wait-for-subscribers fails instead when the wait times out; --no-wait starts at once.
SIGINT and SIGTERM stop it at once.
"""

from __future__ import annotations

import importlib
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection, QosDurability, QosReliability
from rosgraph_msgs.msg import Clock

from ..bags.reading import check_bag_path
from ..errors import BagError, ConfigError
from ..programs import RaisingParser, run_main, stop_handled, summary
from .shutdown import shut_down

_SLICE_S = 0.05  # the longest a wait goes without looking for a shutdown


def message_class(msgtype: str) -> type:
    """The generated Python class of 'pkg/msg/Type'."""
    package, kind, name = msgtype.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError):
        raise BagError(f"unknown message type {msgtype}; is its package built and sourced?") from None


def replay_qos(connection: Connection) -> QoSProfile:
    """The profile ros2 bag play offers for a recorded topic: the recorded publishers' common
    reliability and durability (keep last 10), or reliable and volatile where they differ."""
    offers = list(getattr(connection.ext, "offered_qos_profiles", []) or [])
    profile = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    if offers and all((o.reliability, o.durability) == (offers[0].reliability, offers[0].durability) for o in offers):
        if offers[0].reliability == QosReliability.BEST_EFFORT:
            profile.reliability = ReliabilityPolicy.BEST_EFFORT
        if offers[0].durability == QosDurability.TRANSIENT_LOCAL:
            profile.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return profile


def _sleep(seconds: float) -> bool:
    """Sleep in short slices; False as soon as a signal has shut the context down."""
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        if not rclpy.ok():
            return False
        time.sleep(min(left, _SLICE_S))
    return rclpy.ok()


#: How boom-replay waits for subscribers before it starts.
WAITS = ("lenient", "strict", "none")


def _wait_for_subscribers(node, publishers: Sequence, timeout_s: float, strict: bool) -> bool:
    """Wait until every publisher has a subscriber; after ``timeout_s``, fail (strict) or go on
    with a note. False if a signal shut the context down meanwhile."""
    deadline = time.monotonic() + timeout_s
    while any(p.get_subscription_count() == 0 for p in publishers):
        if not rclpy.ok():
            return False
        if time.monotonic() > deadline:
            topics = ", ".join(p.topic_name for p in publishers if p.get_subscription_count() == 0)
            if strict:
                raise BagError(f"no subscriber appeared within {timeout_s:g} s on {topics} (--wait-timeout)")
            print(
                f"boom-replay: note: no subscriber on {topics} after {timeout_s:g} s; replaying anyway",
                file=sys.stderr,
            )
            return True
        rclpy.spin_once(node, timeout_sec=_SLICE_S)
    return True


def replay(
    bag: Path,
    rate: float,
    topics: Sequence[str],
    start_s: float,
    loop: bool,
    clock: bool,
    wait: str = "lenient",
    wait_timeout_s: float = 10.0,
) -> int:
    """Publish the bag's messages; returns how many were published. ``wait``: one of
    :data:`WAITS` (for subscribers, up to ``wait_timeout_s``: then go on, or fail; or not)."""
    check_bag_path(bag)
    try:
        reader = AnyReader([bag])
        reader.open()
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    rclpy.init()
    node = rclpy.create_node("boom_replay")
    published = 0
    try:
        connections = [c for c in reader.connections if not topics or c.topic in topics]
        missing = set(topics) - {c.topic for c in connections}
        if missing or not connections:
            found = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
            raise BagError(f"{bag}: no topic {', '.join(sorted(missing)) or 'to replay'}; topics: {found}")
        publishers = {
            c.id: node.create_publisher(message_class(c.msgtype), c.topic, replay_qos(c)) for c in connections
        }
        has_clock = any(c.topic == "/clock" for c in connections)
        clock_pub = node.create_publisher(Clock, "/clock", 10) if clock and not has_clock else None
        if clock and has_clock:
            print("boom-replay: the bag has /clock; replaying its own", file=sys.stderr)
        first = reader.start_time + round(start_s * 1e9)
        if first >= reader.end_time:
            length_s = (reader.end_time - reader.start_time) * 1e-9
            raise ConfigError(f"--start {start_s:g} s is past the bag's end ({length_s:.3f} s of messages)")
        if wait != "none":
            waited_for = [publishers[c.id] for c in connections if c.msgcount > 0]
            if not _wait_for_subscribers(node, waited_for, wait_timeout_s, strict=wait == "strict"):
                return published
        print(f"boom-replay: replaying {bag}", file=sys.stderr)
        while True:
            wall0 = time.monotonic()
            for connection, log_ns, raw in reader.messages(connections=connections, start=first):
                if not _sleep(wall0 + (log_ns - first) * 1e-9 / rate - time.monotonic()):
                    return published  # SIGINT/SIGTERM: stop cleanly
                if clock_pub is not None:
                    clock_pub.publish(Clock(clock=Time(nanoseconds=log_ns).to_msg()))
                # counted first: a Ctrl-C raises KeyboardInterrupt at any line, and one between
                # a publish and its count (the moment a user who saw the message presses it)
                # would leave a message that went out uncounted
                published += 1
                publishers[connection.id].publish(bytes(raw))  # CDR as recorded
            if not loop or not rclpy.ok():
                break
        _sleep(0.2)  # let the last messages leave before the node goes
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except KeyboardInterrupt:  # SIGINT that reached Python before rclpy shut the context down
        stop_handled()  # (its way to end: what comes after it is not the stop)
        return published
    finally:
        reader.close()
        node.destroy_node()
        shut_down()
    return published


def check_number(option: str, value: float, expected: str, fits) -> None:
    """Raise ConfigError unless ``value`` is finite and ``fits``: one line naming the option."""
    if not math.isfinite(value) or not fits(value):
        raise ConfigError(f"{option} {value:g}: expected {expected}, a finite number")


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-replay", description=summary(__doc__))
        parser.add_argument("bag", type=Path, help="bag folder or .mcap file")
        parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1)")
        parser.add_argument("--topics", nargs="+", default=[], help="only these topics (default: all)")
        parser.add_argument("--start", type=float, default=0.0, help="skip this many seconds from the start")
        parser.add_argument("--loop", action="store_true", help="play again and again until Ctrl-C")
        parser.add_argument("--clock", action="store_true", help="publish /clock with the recorded times")
        waiting = parser.add_mutually_exclusive_group()
        waiting.add_argument(
            "--wait-for-subscribers",
            action="store_const",
            dest="wait",
            const="strict",
            default="lenient",
            help="fail unless every topic with messages to replay has a subscriber within --wait-timeout "
            "(by default it waits as long and then replays anyway)",
        )
        waiting.add_argument(
            "--no-wait", action="store_const", dest="wait", const="none", help="start at once, subscribers or not"
        )
        parser.add_argument(
            "--wait-timeout", type=float, default=10.0, help="seconds to wait for subscribers (default 10)"
        )
        args = parser.parse_args(argv)
        check_number("--rate", args.rate, "a speed factor > 0", lambda v: v > 0)
        check_number("--start", args.start, "a number of seconds >= 0", lambda v: v >= 0)
        check_number("--wait-timeout", args.wait_timeout, "a number of seconds > 0", lambda v: v > 0)
        count = replay(
            args.bag,
            args.rate,
            args.topics,
            args.start,
            args.loop,
            args.clock,
            args.wait,
            args.wait_timeout,
        )
        print(f"boom-replay: published {count} messages from {args.bag}")
        return 0

    code = run_main("boom-replay", body)
    return 0 if code == 130 else code  # Ctrl-C during set-up ends a replay as a user asked too


if __name__ == "__main__":
    sys.exit(main())
