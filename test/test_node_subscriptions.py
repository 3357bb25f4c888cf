"""The node's subscriptions, in process: made without rclpy's default QoS event handlers, and
their publishers looked up by the topic names as the node gave them (remapped once)."""

from __future__ import annotations

import time

import pytest
from conftest import GUARD_S

rclpy = pytest.importorskip("rclpy")
from rclpy.event_handler import EventHandler  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402


@pytest.fixture
def sim_node():
    """boom_sim under use_sim_time, its trajectory topic remapped twice over: a rule for
    the name it gives, then a rule for the name that rule gives (rcl applies the first that
    matches a name, once)."""
    from boom_hydraulics.ros.node import BoomSimNode

    remaps = ["-r", "~/joint_trajectory:=/boom_goal", "-r", "/boom_goal:=/elsewhere"]
    rclpy.init(args=["--ros-args", *remaps, "-p", "record:=false", "-p", "use_sim_time:=true"])
    try:
        node = BoomSimNode()
        yield node
        node.destroy()
    finally:
        rclpy.shutdown()


def test_no_subscription_or_publisher_carries_a_qos_event_handler(sim_node):
    """Each handler would be a waitable the executor walks in Python at every command."""
    topics = {subscription.topic_name for subscription in sim_node.subscriptions}
    assert {"/valve_command", "/commands", "/boom_goal", "/clock"} <= topics, topics
    assert not [w for w in sim_node.waitables if isinstance(w, EventHandler)]


class _Warnings:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, line: str) -> None:
        self.lines.append(line)


def test_the_watch_names_a_publisher_on_the_remapped_topic_once(sim_node, monkeypatch):
    """A best-effort publisher on /boom_goal, where the trajectories arrive, is named; one on
    /elsewhere (where a second remap of /boom_goal would look) reaches nothing of the node's.
    Of the publishers on /boom_goal, the reliable one alone is counted as reaching the node
    (what the bag records as offered, and the command intake counts as publishers)."""
    warnings = _Warnings()
    monkeypatch.setattr(sim_node, "get_logger", lambda: warnings)
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    # (nodes of their own, not remapped: the warning names the node)
    goal = rclpy.create_node("goal_publisher", use_global_arguments=False)
    elsewhere = rclpy.create_node("elsewhere_publisher", use_global_arguments=False)
    reliable = rclpy.create_node("reliable_goal_publisher", use_global_arguments=False)
    try:
        goal.create_publisher(JointTrajectory, "/boom_goal", best_effort)
        elsewhere.create_publisher(JointTrajectory, "/elsewhere", best_effort)
        reliable.create_publisher(JointTrajectory, "/boom_goal", QoSProfile(depth=10))
        deadline = time.monotonic() + GUARD_S
        reaching: dict = {}
        # until the graph shows all three (goal's name for /elsewhere is not remapped)
        while time.monotonic() < deadline:
            reaching = sim_node.publisher_watch.look()
            if warnings.lines and reaching["/boom_goal"] and goal.count_publishers("/elsewhere") == 1:
                break
            time.sleep(0.01)
        reaching = sim_node.publisher_watch.look()  # once more: not named again
        by_topic = sim_node.publisher_watch.reaching("/boom_goal")
    finally:
        for node in (goal, elsewhere, reliable):
            node.destroy_node()
    assert len(warnings.lines) == 1, warnings.lines
    assert warnings.lines[0].startswith("publisher /goal_publisher on /boom_goal offers QoS"), warnings.lines
    assert "--qos-reliability reliable --qos-durability volatile" in warnings.lines[0]
    assert [info.node_name for info in reaching["/boom_goal"]] == ["reliable_goal_publisher"]
    assert [info.node_name for info in by_topic] == ["reliable_goal_publisher"]
    assert reaching["/valve_command"] == [] and reaching["/clock"] == []


@pytest.mark.parametrize("second_type", ["std_msgs/String", "ValveCommand"])
def test_a_lone_publishers_gaps_are_lost_commands_beside_one_that_cannot_reach(sim_node, second_type):
    """Beside a ValveCommand publisher, a publisher of another type on /valve_command reaches
    nothing: the first is still the topic's one publisher, and the gaps in its sequence
    numbers are commands lost on the way. Beside a second ValveCommand publisher, the
    sequence numbers of two publishers interleave: no gap is a loss, and none is counted."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from boom_hydraulics_msgs.msg import ValveCommand

    # (the other publisher in a context of its own: one DDS participant takes one type per topic)
    context = rclpy.Context()
    rclpy.init(context=context)
    valve = rclpy.create_node("valve_publisher", use_global_arguments=False)
    other = rclpy.create_node("other_publisher", use_global_arguments=False, context=context)
    try:
        valve.create_publisher(ValveCommand, "/valve_command", 10)
        other.create_publisher(String if second_type == "std_msgs/String" else ValveCommand, "/valve_command", 10)
        deadline = time.monotonic() + GUARD_S
        while time.monotonic() < deadline and len(sim_node.get_publishers_info_by_topic("/valve_command")) < 2:
            time.sleep(0.01)
        assert len(sim_node.get_publishers_info_by_topic("/valve_command")) == 2  # (both seen: the test holds)
        sim_node.on_second()  # the node's look at the graph, once a second
        data = serialize_message(ValveCommand(opening=0.1))
        for sequence in (1, 2, 5, 6):  # 3 and 4 never arrived
            sim_node.commands.on_valve_command(data, {"publication_sequence_number": sequence})
    finally:
        for node in (valve, other):
            node.destroy_node()
        rclpy.shutdown(context=context)
    counts = sim_node.commands.counts
    assert counts.received == 4
    assert counts.lost == (2 if second_type == "std_msgs/String" else 0)


def test_a_warning_waits_for_the_publishers_node_name_and_goes_without_it_in_the_end():
    """The graph shows an endpoint a moment before its node's name (rmw's placeholder names
    it meanwhile): the warning waits a few looks for the name; a publisher whose node never
    shows (a DDS writer outside ROS) is named as such, once."""
    from types import SimpleNamespace

    from rclpy.qos import QoSProfile

    from boom_hydraulics.ros.publishers import NAME_WAIT_LOOKS, UNKNOWN_NODE, PublisherWatch
    from boom_hydraulics_msgs.msg import ValveCommand

    class Subscription:  # (hashable, as rclpy's: the watch keys the names as given by subscription)
        topic_name, msg_type, qos_profile = "/valve_command", ValveCommand, QoSProfile(depth=5)

    subscription = Subscription()

    def endpoint(gid: int, name: str) -> SimpleNamespace:
        return SimpleNamespace(
            node_name=name,
            node_namespace="/" if name != UNKNOWN_NODE else "_NODE_NAMESPACE_UNKNOWN_",
            topic_type="std_msgs/msg/String",
            qos_profile=QoSProfile(depth=10),
            endpoint_gid=[gid],
        )

    warnings = _Warnings()
    graph: list[SimpleNamespace] = []
    node = SimpleNamespace(subscriptions=[subscription], get_logger=lambda: warnings)
    node.get_publishers_info_by_topic = lambda topic: list(graph)
    watch = PublisherWatch(node, {subscription: "valve_command"})
    graph.append(endpoint(1, UNKNOWN_NODE))  # its node's name comes a look later
    watch.look()
    assert warnings.lines == []
    graph[0] = endpoint(1, "talker")
    watch.look()
    assert [line.split(" sends ")[0] for line in warnings.lines] == ["publisher /talker"]
    graph[:] = [endpoint(2, UNKNOWN_NODE)]  # never named
    for _ in range(NAME_WAIT_LOOKS + 3):
        watch.look()
    assert [line.split(" sends ")[0] for line in warnings.lines] == ["publisher /talker", "publisher of no known node"]
