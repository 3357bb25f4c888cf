"""The node as the plant behind ros2_control's JointState topic hardware interface: sensor_msgs/JointState
commands on joint_commands, its robot_description's ros2_control tag, the interface's default topics."""

from __future__ import annotations

import math
import time
import xml.etree.ElementTree as ElementTree

import pytest
from conftest import BOOM_SIM, GUARD_S

rclpy = pytest.importorskip("rclpy")
from rcl_interfaces.msg import Log  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]

#: The controller's dead-band (config/default.yaml): a settled boom is within twice it.
DEADBAND = 0.002
#: How far the boom sinks with the valve closed after ~/reset, rad. The reset's rest state has the
#: rod chamber at tank pressure; the closed spool's leakage (valve_leakage_m3_s_pa) fills it, and
#: the boom settles down by 3.1 mrad over 15 s (1.8 of it in the first 4 s), then creeps on at the
#: load-holding valve's seat leakage (4 urad/s): default.yaml, 50 kg, as the model computes it.
RESET_SETTLING_RAD = 0.004
#: What the hardware interface publishes with: reliable, keep-last 1 (rclcpp::QoS(1)).
HARDWARE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: /rosout as the node's log keeps it.
LOGS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def joint_command(
    names: tuple[str, ...] = ("boom_joint",),
    position: float | None = None,
    velocity: float | None = None,
    stamp_s: float | None = None,
) -> JointState:
    """A JointState as the hardware interface writes it: one value per name in the arrays of its
    command interfaces (the same value for every name here)."""
    msg = JointState(name=list(names))
    if position is not None:
        msg.position = [position] * len(names)
    if velocity is not None:
        msg.velocity = [velocity] * len(names)
    if stamp_s is not None:
        msg.header.stamp.sec = int(stamp_s)
        msg.header.stamp.nanosec = round((stamp_s - int(stamp_s)) * 1e9)
    return msg


class Commander:
    """The test's stand-in for the hardware interface: JointState on joint_commands, sent at every
    spin of the test's node (each message it takes, or every 20 ms) as the interface sends at
    every update; and the node's log."""

    def __init__(self, client, topic: str = "joint_commands") -> None:
        self.client = client
        self.pub = client.node.create_publisher(JointState, topic, HARDWARE_QOS)
        self.logs: list[Log] = []
        client.node.create_subscription(Log, "/rosout", self.logs.append, LOGS)
        self.since = client.node.get_clock().now().to_msg()  # (/rosout is transient local: older logs come too)

    def sending(self, msg: JointState, until, timeout: float = GUARD_S) -> bool:
        """Publish ``msg`` at every spin until ``until()`` (an event); False if the guard passes first."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if until():
                return True
            self.pub.publish(msg)
            rclpy.spin_once(self.client.node, timeout_sec=0.02)
        return until()

    def logged(self, *texts: str) -> bool:
        """Whether the node logged a line with each of ``texts`` since this Commander was made."""
        since = (self.since.sec, self.since.nanosec)
        return any(all(t in e.msg for t in texts) and (e.stamp.sec, e.stamp.nanosec) >= since for e in self.logs)


@pytest.fixture
def commander(node_at_rest, client) -> Commander:
    """A joint command publisher for the class's shared node at rest."""
    assert client.spin_until(lambda: len(client.states) > 5), "no drive_state"
    return Commander(client)


def _settled(client, target: float) -> bool:
    state = client.last()
    return abs(state.boom_angle_rad - target) <= 2 * DEADBAND and state.valve_command == 0.0


class TestJointCommandsOnOneNode:
    """JointState commands on one node (conftest.shared_node), found at rest before each test."""

    def test_a_position_moves_the_boom_there_and_holds_it(self, commander, client):
        target = math.radians(30.0)
        start = client.last().boom_angle_rad
        assert abs(target - start) > 0.2  # (it rests near 8.5 degrees)
        assert commander.sending(joint_command(position=target), lambda: _settled(client, target))
        held_from = client.sim_s()
        # repeated as the interface repeats it, the hold goes on: the valve stays closed, the boom where it is
        assert commander.sending(joint_command(position=target), lambda: client.sim_s() > held_from + 1.0)
        recent = [s for s in client.states if _stamp_s(s) > held_from]
        assert recent and all(abs(s.boom_angle_rad - target) <= 2 * DEADBAND + 5e-4 for s in recent)
        assert all(s.valve_command == 0.0 for s in recent)

    def test_a_velocity_turns_the_boom_at_about_that_rate_and_zero_stops_it(self, commander, client):
        rate = 0.1  # rad/s: the rod's speed follows through the lever, whatever the cylinder length
        # each command carries the setpoint on for command_timeout_s: 5 s, so that a test process a
        # loaded machine holds up between two commands does not stop the boom (node_at_rest puts 0.5 back)
        assert client.set_parameter("command_timeout_s", 5.0).successful
        assert commander.sending(joint_command(velocity=rate), lambda: client.last().boom_rate_rad_s > 0.05)
        began = client.sim_s()
        assert commander.sending(joint_command(velocity=rate), lambda: client.sim_s() > began + 2.0)
        window = [s for s in client.states if began + 0.5 <= _stamp_s(s) <= began + 2.0]
        assert len(window) > 20
        first, last = window[0], window[-1]
        mean = (last.boom_angle_rad - first.boom_angle_rad) / (_stamp_s(last) - _stamp_s(first))
        assert mean == pytest.approx(rate, rel=0.1)
        assert all(0.5 * rate < s.boom_rate_rad_s < 1.5 * rate for s in window)
        # a velocity of 0: the setpoint stops where it is, and the dead-band holds the boom there (after a
        # short ring on the oil's spring)
        assert commander.sending(joint_command(velocity=0.0), lambda: client.last().valve_command == 0.0)
        stopped = client.sim_s()
        assert commander.sending(joint_command(velocity=0.0), lambda: client.sim_s() > stopped + 1.0)
        held = client.last().boom_angle_rad
        assert commander.sending(joint_command(velocity=0.0), lambda: client.sim_s() > stopped + 2.0)
        assert abs(client.last().boom_angle_rad - held) < 2e-3 and client.last().valve_command == 0.0
        assert held > first.boom_angle_rad + 0.1

    def test_a_velocity_beyond_the_drive_leaves_the_setpoint_at_most_0_05_rad_ahead(self, commander, client):
        """2 rad/s, more than a fully open valve gives (about 0.6 rad/s here): the boom runs at
        what it can, and once the velocity is 0 it stops within 0.05 rad of where it was, not
        where a setpoint running at 2 rad/s would have got to (0.7 rad ahead after 0.5 s)."""
        assert client.set_parameter("command_timeout_s", 5.0).successful  # (see the test above)
        assert commander.sending(joint_command(velocity=2.0), lambda: client.last().boom_rate_rad_s > 0.3)
        began = client.sim_s()
        assert commander.sending(joint_command(velocity=2.0), lambda: client.sim_s() > began + 0.5)
        assert client.last().valve_command == 1.0 and client.last().boom_rate_rad_s < 1.0  # wide open: its most
        seen = client.last().boom_angle_rad  # (the node's boom is a little further by now)
        assert commander.sending(joint_command(velocity=0.0), lambda: client.last().valve_command == 0.0)
        stopped = client.sim_s()
        assert commander.sending(joint_command(velocity=0.0), lambda: client.sim_s() > stopped + 1.0)
        assert seen < client.last().boom_angle_rad < seen + 0.05 + 0.03  # (+ what it ran after this client saw it)

    def test_a_velocity_after_a_position_goes_on_from_the_setpoint(self, commander, client):
        """The hardware interface with both command interfaces: a position and the rate from it."""
        target = math.radians(20.0)
        assert commander.sending(joint_command(position=target), lambda: _settled(client, target))
        msg = joint_command(position=target, velocity=-0.1)  # 20 degrees, and down from there at 0.1 rad/s
        # each command starts the setpoint at its position again: sent until the valve opens to lower
        assert commander.sending(msg, lambda: client.last().valve_command < 0.0)
        began = client.sim_s()
        # not renewed, the rate carries the setpoint on for command_timeout_s (0.5 s): 0.05 rad, then it holds
        assert client.spin_until(lambda: client.sim_s() > began + 2.5 and client.last().valve_command == 0.0)
        assert client.last().boom_angle_rad == pytest.approx(target - 0.05, abs=2 * DEADBAND + 1e-3)

    def test_commands_for_another_joint_nan_or_stale_are_ignored_with_a_warning(self, commander, client):
        rest = client.last().boom_angle_rad
        sent_s = client.sim_s()
        for msg, text in (
            (joint_command(("cylinder_joint",), position=1.6), "it names ['cylinder_joint']"),
            (joint_command(position=math.nan), "position nan of boom_joint is not finite"),
            (joint_command(), "neither a position nor a velocity"),
            (joint_command(position=0.5, stamp_s=time.time() - 2.0), "it is stale"),
            (joint_command(position=math.radians(85.0)), "lies outside the stroke's"),
        ):
            assert commander.sending(msg, lambda text=text: commander.logged("joint command ignored: ", text)), text
        # none of them moved the valve: the boom rests where it was, never up towards a position sent,
        # and down only by the settling after the fixture's ~/reset (see RESET_SETTLING_RAD)
        since = [s for s in client.states if _stamp_s(s) > sent_s]
        assert since and all(s.valve_command == 0.0 for s in since)
        assert all(rest - RESET_SETTLING_RAD < s.boom_angle_rad <= rest for s in since)

    def test_a_command_stamped_ahead_acts_at_its_stamp(self, commander, client):
        target = math.radians(25.0)
        at_s = time.time() + 1.0  # the node's own clock: stamps are ROS (wall) time
        assert commander.sending(joint_command(position=target, stamp_s=at_s), lambda: _settled(client, target))
        moved = [s for s in client.states if abs(s.valve_command) > 1e-3]  # (not a late handshake's)
        # not before the step that starts within half a step of its stamp (a state is stamped at its tick's end)
        assert moved and _stamp_s(moved[0]) >= at_s - 0.001

    def test_a_joint_command_preempts_a_goal_and_a_valve_command_overrides_it(self, commander, client):
        from action_msgs.msg import GoalStatus
        from rclpy.action import ActionClient

        from boom_hydraulics_msgs.action import MoveBoom

        action = ActionClient(client.node, MoveBoom, "/boom_sim/move_boom")
        assert action.wait_for_server(timeout_sec=GUARD_S), "no MoveBoom action server"
        sent = action.send_goal_async(MoveBoom.Goal(target_angle_rad=math.radians(60.0), max_speed_rad_s=0.05))
        assert client.spin_until(sent.done) and sent.result().accepted
        assert client.spin_until(lambda: client.last().boom_rate_rad_s > 0.02)  # the slow goal moves the boom
        result = sent.result().get_result_async()
        target = math.radians(5.0)
        assert commander.sending(joint_command(position=target), result.done)
        answer = result.result()
        assert answer.status == GoalStatus.STATUS_ABORTED
        assert answer.result.message == "preempted by a joint command on joint_commands"
        assert commander.sending(joint_command(position=target), lambda: _settled(client, target))
        # a valve command takes the valve from the joint commands, which no longer drive after it
        assert client.spin_until(lambda: client.last().valve_command == 0.3, opening=0.3)
        assert client.spin_until(lambda: client.last().boom_angle_rad > target + 0.05, opening=0.3)
        action.destroy()


def test_remapped_to_the_interface_defaults_it_is_driven_there_and_describes_it(nodes, client):
    """Remapped to joint_state_topic_hardware_interface's default topics, the node takes its commands
    on /robot_joint_commands, publishes boom_joint on /robot_joint_states, and its robot_description's
    ros2_control tag names both, with boom_joint's position and velocity interfaces."""
    nodes.start(ros_args=["-r", "joint_commands:=/robot_joint_commands", "-r", "joint_states:=/robot_joint_states"])
    descriptions: list[String] = []
    states: list[JointState] = []
    client.node.create_subscription(String, "robot_description", descriptions.append, LATCHED)
    client.node.create_subscription(JointState, "/robot_joint_states", states.append, HARDWARE_QOS)
    assert client.spin_until(lambda: descriptions and states), "no robot_description or /robot_joint_states"
    robot = ElementTree.fromstring(descriptions[-1].data)
    (control,) = robot.findall("ros2_control")
    hardware = control.find("hardware")
    assert hardware.findtext("plugin") == "joint_state_topic_hardware_interface/JointStateTopicSystem"
    params = {p.get("name"): p.text for p in hardware.findall("param")}
    assert params["joint_commands_topic"] == "/robot_joint_commands"
    assert params["joint_states_topic"] == "/robot_joint_states"
    (joint,) = control.findall("joint")
    assert [c.get("name") for c in joint.findall("command_interface")] == ["position", "velocity"]
    assert [c.get("name") for c in joint.findall("state_interface")] == ["position", "velocity"]
    # the tag's joint is the URDF's revolute boom joint, and the states name it
    urdf_joint = next(j for j in robot.findall("joint") if j.get("name") == joint.get("name"))
    assert urdf_joint.get("type") == "revolute" and "boom_joint" in states[-1].name

    commander = Commander(client, "/robot_joint_commands")
    target = math.radians(15.0)

    def there() -> bool:
        values = dict(zip(states[-1].name, states[-1].position))
        return abs(values["boom_joint"] - target) <= 2 * DEADBAND

    assert commander.sending(joint_command(position=target), there)
    assert not client.joints  # nothing on the name it was remapped from
