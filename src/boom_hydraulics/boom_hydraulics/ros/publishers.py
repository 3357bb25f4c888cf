"""The publishers of the node's subscriptions, looked up once a second: one warning line for
each publisher whose messages cannot arrive.

A publisher cannot reach a subscription when it sends another message type on the topic,
or when it offers QoS the subscription cannot take (a best-effort publisher and the
reliable ``~/joint_trajectory``). The line names the publishing node, the topic and what
to change, once per publisher (a publisher that comes back is a new one).

This stands in for rclpy's default event handlers on the subscriptions, which say the same
as soon as DDS notices. Each of those handlers is a waitable that the executor goes through
in Python at every message the node receives (two wait sets per command); the node creates
its subscriptions without them (docs/performance.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSCompatibility, qos_check_compatible
from rclpy.subscription import Subscription

from .recording import type_name

#: What the graph names an endpoint's node before it knows it (rmw_dds_common): the endpoint
#: shows up a moment before its node's name, and a DDS writer outside ROS never has one.
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
#: Looks at the graph (one a second) that a publisher's warning waits for its node's name.
NAME_WAIT_LOOKS = 3


def node_path(info: Any) -> str:
    """The fully qualified name of the node behind a graph endpoint (TopicEndpointInfo)."""
    if info.node_name == UNKNOWN_NODE:
        return "of no known node"
    namespace = info.node_namespace.rstrip("/")
    return f"{namespace}/{info.node_name}"


def unreachable(info: Any, topic: str, msg_type: str, qos: Any) -> str | None:
    """Why the publisher ``info`` (TopicEndpointInfo) on ``topic`` cannot reach a subscription
    of type ``msg_type`` ('pkg/msg/Type') with QoS profile ``qos``; None when it can."""
    if info.topic_type != msg_type:
        return (
            f"publisher {node_path(info)} sends {info.topic_type} on {topic}, where this node takes "
            f"{msg_type}: none of its messages arrive; publish {msg_type} there"
        )
    compatibility, reason = qos_check_compatible(info.qos_profile, qos)
    if compatibility == QoSCompatibility.ERROR:
        reason = reason.strip().removeprefix("ERROR:").strip().rstrip(";").lower()  # (rcl's words)
        return (
            f"publisher {node_path(info)} on {topic} offers QoS this node's subscription cannot take "
            f"({reason}): none of its messages arrive; publish with {_qos_words(qos)}"
        )
    return None


def _qos_words(qos: Any) -> str:
    """The policies of a subscription's QoS profile that a publisher must match, as
    ``ros2 topic pub`` takes them."""
    return f"--qos-reliability {qos.reliability.name.lower()} --qos-durability {qos.durability.name.lower()}"


class PublisherWatch:
    """The publishers of the node's subscriptions: :meth:`reaching` a topic, and :meth:`look`
    once a second from the node's timer (one graph lookup per subscription).

    ``topics`` maps each subscription to its topic name as the node gave it, so that rclpy
    expands and remaps it once here, as it did when subscribing (the subscription's own
    ``topic_name`` is already remapped: a second remap is wrong under chained rules)."""

    def __init__(self, node: Node, topics: Mapping[Subscription, str]) -> None:
        self.node, self.topics = node, topics
        self._told: set[tuple[int, ...]] = set()  # endpoint gids warned about, while they publish
        self._unnamed: dict[tuple[int, ...], int] = {}  # looks that saw a gid without its node's name

    def _publishers(self, subscription: Subscription) -> list[tuple[Any, str | None]]:
        """The publishers on the subscription's topic (TopicEndpointInfo), each with why its
        messages cannot arrive there (:func:`unreachable`; None when they can)."""
        topic, msg_type = subscription.topic_name, type_name(subscription.msg_type)
        return [
            (info, unreachable(info, topic, msg_type, subscription.qos_profile))
            for info in self.node.get_publishers_info_by_topic(self.topics[subscription])
        ]

    def reaching(self, topic: str) -> list[Any]:
        """The publishers (TopicEndpointInfo) whose messages can arrive at this node's
        subscription of ``topic`` (its resolved name): of its type, with QoS it takes."""
        for subscription in self.node.subscriptions:
            if subscription.topic_name == topic:
                return [info for info, why in self._publishers(subscription) if why is None]
        return []

    def look(self) -> dict[str, list[Any]]:
        """Warn once about each publisher that cannot reach its subscription; the publishers
        that can, by resolved topic name (what the bag and the command intake count)."""
        seen: set[tuple[int, ...]] = set()
        reaching: dict[str, list[Any]] = {}
        for subscription in self.node.subscriptions:
            arrive = reaching.setdefault(subscription.topic_name, [])
            for info, why in self._publishers(subscription):
                gid = tuple(info.endpoint_gid)
                seen.add(gid)
                if why is None:
                    arrive.append(info)
                elif gid not in self._told and not self._name_pending(gid, info):
                    self._told.add(gid)
                    self.node.get_logger().warning(why)
        self._told &= seen  # gone publishers: forgotten
        self._unnamed = {gid: looks for gid, looks in self._unnamed.items() if gid in seen}
        return reaching

    def _name_pending(self, gid: tuple[int, ...], info: Any) -> bool:
        """Whether the warning about a publisher waits for its node's name: the graph may show
        it a look later; after NAME_WAIT_LOOKS looks without it, the warning goes without it."""
        if info.node_name != UNKNOWN_NODE:
            return False
        looks = self._unnamed[gid] = self._unnamed.get(gid, 0) + 1
        return looks <= NAME_WAIT_LOOKS
