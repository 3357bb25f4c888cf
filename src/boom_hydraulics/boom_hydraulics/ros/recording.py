"""The node's bag: every topic it publishes, its parameter changes and every command it receives.

The bag starts with the stepping (its time origin, simulated time 0): at start on the node's
own clock, at the first /clock on a shared one. Commands received before it are kept for it, and
so are the paths the position controller took meanwhile (~/setpoint_path).
Messages are serialised once: the bytes published are the bytes recorded. A recording that
fails (a full disk) stops with one error line; the run goes on. On a shared clock (``ordered``),
which stands still between its ticks, what the node handles at one clock reading is logged
1 ns apart, in the order it handled it: the bag then tells whether a command came before or
after a tick's states (boom-resim needs it).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from rcl_interfaces.msg import ParameterEvent
from rclpy.node import Node
from rclpy.qos import qos_profile_parameter_events
from rclpy.serialization import serialize_message
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

from ..bags.encoding import parameter_event_cdr
from ..bags.recording import BagRecorder, Topic, new_bag_folder, offered_qos

PARAMETER_EVENTS = "/parameter_events"


def type_name(msg_type: Any) -> str:
    """'pkg/msg/Type' of a generated message class."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def _qos_time(duration: Any) -> QosTime:
    sec, nsec = divmod(duration.nanoseconds, 1_000_000_000)
    return QosTime(sec=sec, nsec=nsec)


def _offers(publishers: Iterable[Any]) -> tuple[Qos, ...]:
    """What the publishers (TopicEndpointInfo) of a topic offer (as ``ros2 bag record`` records it)."""
    return tuple(offer_of(info.qos_profile) for info in publishers)


def offer_of(profile: Any) -> Qos:
    """A discovered publisher's QoS profile (rclpy) as rosbag2 records it."""
    return Qos(
        history=QosHistory(int(profile.history)),
        depth=profile.depth,
        reliability=QosReliability(int(profile.reliability)),
        durability=QosDurability(int(profile.durability)),
        deadline=_qos_time(profile.deadline),
        lifespan=_qos_time(profile.lifespan),
        liveliness=QosLiveliness(int(profile.liveliness)),
        liveliness_lease_duration=_qos_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


class NodeRecording:
    """The bag of one node, if asked for (``record``), and the glue between it and the topics."""

    def __init__(
        self,
        node: Node,
        now_ns: Callable[[], int],
        command_topics: dict[str, Any],
        publishers_of: Callable[[str], Sequence[Any]],
        *,
        record: bool,
        folder: str,
        chunk_kib: float,
        flush_s: float,
        ordered: bool = False,
    ) -> None:
        self.node = node
        self.now_ns = now_ns
        self.command_topics = command_topics  # resolved name -> message type
        self.publishers_of = publishers_of  # resolved name -> the publishers that reach it
        self.pending = record  # asked for, not yet begun (FOLLOWED: no /clock yet)
        self.recorder: BagRecorder | None = None
        self.error: str | None = None
        self._folder, self._chunk_kib, self._flush_s = folder, chunk_kib, flush_s
        # what comes before the bag begins, to go into it then, in order: the commands received
        # and what the node published to be kept (each a call that records it)
        self._early: list[Callable[[], None]] = []
        self._topic_names: dict[Any, str] = {}  # publisher -> its topic (rclpy asks rcl at each read)
        self._ordered = ordered
        self._last_log_ns = -1  # the last log time given (ordered)

    def _log_time(self, now_ns: int) -> int:
        """The log time of what the node handles now: ``now_ns``, or, ``ordered``, 1 ns after the
        last one given where the clock has not moved since."""
        if self._ordered:
            now_ns = self._last_log_ns = max(now_ns, self._last_log_ns + 1)
        return now_ns

    def begin(self, publishers: Sequence[Any], custom_data: dict[str, str]) -> None:
        """Open the bag, if asked for, at the time origin, with the commands received before it
        (and the messages published to be kept: see publish)."""
        if not self.pending:
            return
        self.pending = False
        self._open(publishers, custom_data)
        for early in self._early:
            early()
        self._early.clear()

    def _open(self, publishers: Sequence[Any], custom_data: dict[str, str]) -> None:
        """Start :attr:`recorder`: a bag of the given publishers' topics, the parameter changes,
        and every command received (each command topic once its first publisher shows up)."""
        topics = [Topic(p.topic_name, type_name(p.msg_type), (offer_of(p.qos_profile),)) for p in publishers]
        events_qos = offered_qos(depth=qos_profile_parameter_events.depth)
        topics.append(Topic(PARAMETER_EVENTS, type_name(ParameterEvent), (events_qos,)))
        recorder = BagRecorder(
            new_bag_folder(self._folder, self.node.get_fully_qualified_name()),
            topics,
            chunk_size=round(self._chunk_kib * 1024),
            custom_data=custom_data,
            flush_s=self._flush_s,
        )
        self.recorder = recorder  # at once: from here on, finish() finishes it, whatever comes
        self.node.get_logger().info(f"recording to {recorder.folder}")

    def publish(self, messages: list[tuple[Any, Any]], log_ns: int, keep_early: bool = False) -> None:
        """Record (publisher, message) pairs, then publish them all: whatever a subscriber got
        is in the bag, even when a signal shuts the ROS context down in the middle of a
        tick's publishing (a tick is recorded whole; only its publishing can be cut short).
        While recording, each message is serialised once, and the bytes published are the
        bytes recorded. A message given as CDR bytes is published and recorded as those bytes.
        ``keep_early``: messages (CDR bytes) published before the bag begins (no /clock yet) go
        into it when it begins, in order with the commands received meanwhile."""
        if self.pending and keep_early:
            self._early += [functools.partial(self._write_now, publisher, data) for publisher, data in messages]
        if self.recorder is None:
            for publisher, msg in messages:
                publisher.publish(msg)
            return
        serialised = [
            (publisher, msg if isinstance(msg, bytes) else serialize_message(msg)) for publisher, msg in messages
        ]
        log_ns = self._log_time(log_ns)
        for publisher, data in serialised:
            self._write(publisher, data, log_ns)
        for publisher, data in serialised:
            publisher.publish(data)

    def _write_now(self, publisher: Any, data: bytes) -> None:
        """Record ``data`` as published by ``publisher`` now (a message kept from before the bag)."""
        self._write(publisher, data, self._log_time(self.now_ns()))

    def _write(self, publisher: Any, data: bytes, log_ns: int) -> None:
        """Record ``data`` as published by ``publisher`` (at ``log_ns`` as given: see _log_time)."""
        assert self.recorder is not None
        name = self._topic_names.get(publisher)
        if name is None:
            name = self._topic_names[publisher] = publisher.topic_name
        self.recorder.write(name, log_ns, data)

    def parameter_event(self, changed_at_ns: int, changed: list[tuple[str, int, Any]]) -> None:
        """Record a parameter change as rclpy announces it on /parameter_events, stamped with
        the node-clock time of the simulated instant it took effect at (boom-resim applies it there)."""
        if self.recorder is None:
            return
        data = parameter_event_cdr(self.node.get_fully_qualified_name(), changed_at_ns, changed)
        self.recorder.write(PARAMETER_EVENTS, self._log_time(self.now_ns()), data)

    def watch_command_topics(self, publishers: Mapping[str, Sequence[Any]]) -> None:
        """Once a second, with the publishers (TopicEndpointInfo) that reach each command topic:
        declare a command topic once it has one; keep its offers up to date."""
        if self.recorder is None:
            return
        for topic, msg_type in self.command_topics.items():
            offers = _offers(publishers.get(topic, ()))
            if offers and topic not in self.recorder.topics:
                self.recorder.add_topic(Topic(topic, type_name(msg_type), offers))
            self.recorder.add_offers(topic, offers)

    def received(self, topic: str, data: bytes, info: dict) -> None:
        """Log a received command at its receive time on the node's clock, as rosbag2 does
        (its header stamp stays inside the message); publish time: when it was sent."""
        if self.pending:
            self._early.append(functools.partial(self.received, topic, data, info))
            return
        if self.recorder is None:
            return
        if topic not in self.recorder.topics:
            offers = _offers(self.publishers_of(topic)) or (offered_qos(),)
            self.recorder.add_topic(Topic(topic, type_name(self.command_topics[topic]), offers))
        received = self._log_time(self.now_ns())
        self.recorder.write(topic, received, data, info.get("source_timestamp") or received)

    def watch(self) -> None:
        """A recording that failed (a full disk) stops with one error line; the run goes on."""
        if self.recorder is not None and self.error is None and self.recorder.error is not None:
            self.error = self.recorder.error
            self.node.get_logger().error(f"recording stopped: {self.error}; the simulation goes on")

    def status(self) -> tuple[str | None, str]:
        """(the error that stopped the recording or None, the bag's folder) while recording."""
        self.watch()
        return self.error, str(self.recorder.folder) if self.recorder is not None else ""

    def finish(self, started: bool = True) -> bool:
        """Finish the bag and say where it is; False when the recording failed (the bag is
        left for boom-bag-recover). ``started``: False when a signal stopped the node before
        its stepping started (then a bag not yet begun is no surprise to say)."""
        if self.pending and started:
            print("boom_sim: no bag: /clock never arrived (use_sim_time), so the run never started", flush=True)
        recorder = self.recorder
        if recorder is None:
            return True
        folder = recorder.close()
        counts = ", ".join(f"{t} {n}" for t, n in recorder.counts.items() if n)
        if recorder.error is not None:  # (it says how to recover the bag)
            print(f"boom_sim: error: recording failed: {recorder.error}", file=sys.stderr, flush=True)
            return False
        print(f"boom_sim: bag {folder} ({counts})", flush=True)
        return True
