"""Position goals for the node in its own process: MoveBoom, ~/joint_trajectory, override."""

from __future__ import annotations

import itertools
import math
import os
import re
import signal
import time

import numpy as np
import pytest
from conftest import BOOM_SIM, GUARD_S, run_tool

rclpy = pytest.importorskip("rclpy")
from action_msgs.msg import GoalStatus  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from rcl_interfaces.msg import Log  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from boom_hydraulics_msgs.action import MoveBoom  # noqa: E402
from boom_hydraulics_msgs.msg import SetpointPath  # noqa: E402

pytestmark = [
    pytest.mark.usefixtures("ros_context"),
    pytest.mark.skipif(BOOM_SIM is None, reason="boom_sim not on PATH (run through tools/with-env)"),
]

#: The controller's dead-band (config/default.yaml): a settled boom is within twice it.
DEADBAND = 0.002


class Mover:
    """The test's action client and trajectory publisher."""

    def __init__(self, client) -> None:
        self.client = client
        self.action = ActionClient(client.node, MoveBoom, "/boom_sim/move_boom")
        self.trajectories = client.node.create_publisher(
            JointTrajectory, "/boom_sim/joint_trajectory", QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        )
        self.feedback: list[MoveBoom.Feedback] = []
        self.logs: list[Log] = []
        rosout_qos = QoSProfile(
            depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        client.node.create_subscription(Log, "/rosout", self.logs.append, rosout_qos)
        # /rosout is transient local: a node that ran other tests before hands their logs over too
        self.since = client.node.get_clock().now().to_msg()
        assert self.action.wait_for_server(timeout_sec=GUARD_S), "no MoveBoom action server"
        assert client.spin_until(lambda: len(client.states) > 5), "no drive_state"

    def send(self, target_rad: float, max_speed: float = 0.0):
        """Send a goal; the goal handle once the server answered."""
        future = self.action.send_goal_async(
            MoveBoom.Goal(target_angle_rad=target_rad, max_speed_rad_s=max_speed),
            feedback_callback=lambda m: self.feedback.append(m.feedback),
        )
        assert self.client.spin_until(future.done, 10)
        return future.result()

    def result(self, handle, timeout: float = 20.0):
        future = handle.get_result_async()
        assert self.client.spin_until(future.done, timeout), "no result"
        return future.result()

    def logged(self, text: str) -> bool:
        """Whether the node logged ``text`` since this Mover was made."""
        since = (self.since.sec, self.since.nanosec)
        return any(text in entry.msg and (entry.stamp.sec, entry.stamp.nanosec) >= since for entry in self.logs)

    def accepted_targets_rad(self) -> list[float]:
        """The targets of the goals the node accepted since this Mover was made, in the order it
        logged them ("MoveBoom: a -> b deg ...")."""
        since = (self.since.sec, self.since.nanosec)
        found = (
            re.match(r"MoveBoom: \S+ -> (\S+) deg", entry.msg)
            for entry in self.logs
            if (entry.stamp.sec, entry.stamp.nanosec) >= since
        )
        return [math.radians(float(m.group(1))) for m in found if m is not None]


@pytest.fixture
def mover(node_at_rest, client) -> Mover:
    """The action client and trajectory publisher, for the class's shared node at rest."""
    return Mover(client)


def _trajectory(points: list[tuple[float, float]]) -> JointTrajectory:
    msg = JointTrajectory(joint_names=["boom_joint"])
    for t, angle in points:
        sec = int(t)
        msg.points.append(
            JointTrajectoryPoint(positions=[angle], time_from_start=Duration(sec=sec, nanosec=round((t - sec) * 1e9)))
        )
    return msg


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


class TestMovesOnOneNode:
    """Position goals on one node (conftest.shared_node), found at rest before each test."""

    def test_move_boom_reaches_30_degrees_and_holds_it(self, mover, client):
        target = math.radians(30.0)
        handle = mover.send(target)
        assert handle.accepted
        answer = mover.result(handle)
        assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.message
        result = answer.result
        assert abs(result.final_error_rad) <= 2 * DEADBAND
        assert 1.0 < result.duration_s < 6.0 and result.supply_energy_j > 100.0
        assert len(mover.feedback) >= 5 and all(abs(f.error_rad) < 0.5 for f in mover.feedback)
        client.spin_sim(2.0)  # it holds: the valve stays closed and the boom where it is
        recent = client.states[-100:]
        assert all(abs(s.boom_angle_rad - target) <= 2 * DEADBAND + 5e-4 for s in recent)
        assert all(s.valve_command == 0.0 for s in recent)

    def test_cancel_stops_the_boom_and_closes_the_valve(self, mover, client):
        handle = mover.send(math.radians(60.0))
        assert client.spin_until(lambda: client.last().boom_rate_rad_s > 0.1, timeout=60)  # moving
        cancel = handle.cancel_goal_async()
        assert client.spin_until(cancel.done, 10)
        answer = mover.result(handle)
        assert answer.status == GoalStatus.STATUS_CANCELED
        client.spin_sim(1.0)  # the closed valve stops the boom (after a short ring on the oil's spring)
        stopped = client.last()
        assert stopped.valve_command == 0.0 and abs(stopped.boom_rate_rad_s) < 0.01
        client.spin_sim(1.0)
        assert abs(client.last().boom_angle_rad - stopped.boom_angle_rad) < 1e-3

    def test_a_second_goal_preempts_the_first(self, mover, client):
        first = mover.send(math.radians(50.0))
        client.spin_sim(0.7)
        second = mover.send(math.radians(15.0))
        assert second.accepted
        answer = mover.result(first)
        assert answer.status == GoalStatus.STATUS_ABORTED and "preempted" in answer.result.message
        answer = mover.result(second)
        assert answer.status == GoalStatus.STATUS_SUCCEEDED
        assert abs(client.last().boom_angle_rad - math.radians(15.0)) <= 2 * DEADBAND + 5e-4

    def test_a_goal_outside_the_stroke_is_rejected_with_a_reason(self, mover, client):
        handle = mover.send(math.radians(85.0))
        assert not handle.accepted
        assert client.spin_until(lambda: mover.logged("MoveBoom goal rejected"), 5)
        assert mover.logged("lies outside the stroke's")

    def test_a_valve_command_overrides_and_aborts_the_goal(self, mover, client):
        # a slow goal (35-42 degrees up, from where the boom rests or the test before left it: 12-15 s),
        # still in flight when the override comes on a machine that leaves this process seconds behind
        # the node (at full speed it had settled, 4.55 s, before a loaded clean clone's override came)
        handle = mover.send(math.radians(50.0), max_speed=0.05)
        client.spin_sim(0.5)
        # the goal lifts it first: at rest after ~/reset the boom sinks slowly (the closed spool's
        # leakage fills the rod chamber), which alone would pass for the operator's lowering
        assert client.spin_until(lambda: client.last().boom_rate_rad_s > 0.0)
        assert client.spin_until(lambda: client.last().boom_rate_rad_s < 0.0, opening=-0.5)  # the operator lowers it
        answer = mover.result(handle)
        assert answer.status == GoalStatus.STATUS_ABORTED and "operator override" in answer.result.message
        assert client.last().valve_command == -0.5 and client.last().boom_rate_rad_s < 0.0

    def test_a_joint_trajectory_is_followed_within_a_degree(self, mover, client):
        """Positions only: linear between points, as joint_trajectory_controller does. Tolerance:
        1 degree while moving at up to 0.2 rad/s, 2 x dead-band at the end."""
        points = [(1.0, 0.3), (2.5, 0.6), (4.0, 0.4)]
        # a state's stamp is its simulated instant on the node's clock, the system clock: the
        # states of the trajectory are those stamped after it was sent (a loaded machine may
        # still hand this client states of before, the handshake's opening among them)
        sent_s = time.time()
        mover.trajectories.publish(_trajectory(points))

        def since() -> list:
            return [s for s in client.states if _stamp_s(s) >= sent_s]

        assert client.spin_until(lambda: any(s.valve_command != 0.0 for s in since()))
        start = since()[0].boom_angle_rad
        t0 = next(s for s in since() if s.valve_command != 0.0)  # the start, give or take a step
        begin = _stamp_s(t0)
        assert client.spin_until(lambda: _stamp_s(client.last()) - begin > 5.5)
        states = since()
        knots = [(0.0, start), *points]

        def expected(t: float) -> float:
            for (ta, a), (tb, b) in itertools.pairwise(knots):
                if t <= tb:
                    return a + (b - a) * max(0.0, t - ta) / (tb - ta)
            return knots[-1][1]

        errors = [
            abs(s.boom_angle_rad - expected(s.header.stamp.sec + s.header.stamp.nanosec * 1e-9 - begin)) for s in states
        ]
        assert max(errors) < math.radians(1.0), max(errors)
        assert abs(states[-1].boom_angle_rad - 0.4) <= 2 * DEADBAND + 5e-4
        assert mover.logged("joint trajectory: 3 points over")

    def test_a_valve_command_overrides_a_trajectory(self, mover, client):
        mover.trajectories.publish(_trajectory([(3.0, 0.9)]))
        client.spin_sim(1.0)
        assert client.spin_until(lambda: client.last().boom_rate_rad_s < 0.0, opening=-0.4)
        assert client.spin_until(lambda: mover.logged("joint trajectory aborted: operator override"), 5)
        assert client.last().valve_command == -0.4 and client.last().boom_rate_rad_s < 0.0

    def test_a_burst_of_goals_is_answered_every_one(self, mover, client):
        """100 goals at once, each preempting the one before: every goal and every result gets an
        answer (the server keeps 1000 requests; a client that bursts must keep as many itself)."""
        deep = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        burst = ActionClient(
            client.node, MoveBoom, "/boom_sim/move_boom", goal_service_qos_profile=deep, result_service_qos_profile=deep
        )
        assert burst.wait_for_server(timeout_sec=20)
        sent = [burst.send_goal_async(MoveBoom.Goal(target_angle_rad=0.3 + 0.001 * k)) for k in range(100)]
        assert client.spin_until(lambda: all(f.done() for f in sent), timeout=60), sum(f.done() for f in sent)
        handles = [f.result() for f in sent]
        assert all(h.accepted for h in handles)
        results = [h.get_result_async() for h in handles]
        assert client.spin_until(lambda: all(f.done() for f in results), timeout=120), sum(f.done() for f in results)
        ended = [(f.result().status, f.result().result) for f in results]
        # the node takes the goals in the order they were sent: its log names their targets in turn
        targets = [0.3 + 0.001 * k for k in range(100)]
        assert client.spin_until(lambda: len(mover.accepted_targets_rad()) >= len(targets), timeout=GUARD_S)
        assert mover.accepted_targets_rad() == pytest.approx(targets, abs=2e-4)  # (logged to 0.01 deg)
        for status, result in ended[:-1]:  # each preempted by the next, unless it settled before the next came
            if status == GoalStatus.STATUS_SUCCEEDED:  # (a loaded machine spreads the burst over many ticks)
                assert result.message.startswith("settled") and abs(result.final_error_rad) <= 2 * DEADBAND
            else:
                assert status == GoalStatus.STATUS_ABORTED and result.message.startswith("preempted"), result.message
        assert ended[-1][0] == GoalStatus.STATUS_SUCCEEDED, ended[-1][1].message


@pytest.mark.parametrize("clock", ["publish_clock", "default"])
def test_a_closed_loop_run_resimulates_exactly_and_answers_what_if(nodes, client, tmp_path, clock):
    """A recorded MoveBoom run (one goal held, its move cut by a stall of the node's process, so
    that one tick comes long after the one before, as on a loaded machine; one goal given a new
    payload and gain, then canceled) fed through boom-resim: the controller follows the paths the
    node's controller followed (~/setpoint_path), so that every recorded state comes again, the
    same stamps, the rod to 1e-9 m, the valve opening to 1e-9; with 200 kg it still reaches the
    first target, as a closed loop does. (Interpolating the per-tick setpoints instead, as boom-resim
    did before, missed by up to 0.02 degrees in a loaded suite run, and by far more across the stall.)
    With publish_clock at real-time factor 2, and on the node's default clock (ROS-time stamps)."""
    from bag_checks import check_bag

    from boom_hydraulics.bags.reading import read_drive_states, read_run_description

    pace = ("publish_clock:=true", "real_time_factor:=2.0") if clock == "publish_clock" else ()
    proc = nodes.start(*pace, f"record_folder:={tmp_path / 'bags'}", record=True)
    try:
        mover = Mover(client)
        paths: list[SetpointPath] = []
        client.node.create_subscription(SetpointPath, "/boom_sim/setpoint_path", paths.append, 100)
        first = mover.send(math.radians(30.0))
        client.spin_sim(0.3)  # under way
        os.kill(proc.pid, signal.SIGSTOP)  # starved of the processor: the next tick catches up at once
        time.sleep(0.4)  # (the stall itself, not a wait for something)
        os.kill(proc.pid, signal.SIGCONT)
        assert mover.result(first).status == GoalStatus.STATUS_SUCCEEDED
        client.spin_sim(1.0)  # (simulated s)
        second = mover.send(math.radians(45.0))
        client.spin_sim(0.5)
        client.set_parameter("payload_mass_kg", 150.0)  # the controller takes them, afresh
        client.set_parameter("control_position_gain_1_rad", 2.0)
        client.spin_sim(0.3)  # midway through the second move
        cancel = second.cancel_goal_async()
        assert client.spin_until(cancel.done, 10)
        assert mover.result(second).status == GoalStatus.STATUS_CANCELED
        client.spin_sim(1.0)
        trajectories_s = client.sim_s()
        _trajectories_and_joint_commands(client, mover, paths)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=20)
    (bag,) = list((tmp_path / "bags").iterdir())
    for name, extra in (("same", []), ("heavy", ["--set", "payload_mass_kg=200"])):
        result = run_tool("boom-resim", bag, "--out", tmp_path / name, *extra)
        assert result.returncode == 0, result.stderr
    original, same, heavy = (read_drive_states(p) for p in (bag, tmp_path / "same", tmp_path / "heavy"))
    # the stall: a tick 0.4 s of wall time after the one before (0.8 s of simulated time at factor 2)
    assert np.max(np.diff(original["t"])) > 0.3, np.max(np.diff(original["t"]))
    assert len(same["t"]) == len(original["t"]) > 50
    assert np.array_equal(same["t"], original["t"])
    assert np.max(np.abs(original["q1"] - same["q1"])) < 1e-9
    assert np.max(np.abs(original["u"] - same["u"])) < 1e-9
    # and boom-resim's own bag (the paths and setpoints go with it) re-simulates the same
    result = run_tool("boom-resim", tmp_path / "same", "--out", tmp_path / "once_more")
    assert result.returncode == 0, result.stderr
    assert np.array_equal(read_drive_states(tmp_path / "once_more")["q1"], same["q1"])
    # the heavy what-if: settled at 30 degrees before the second goal, then stopped by the cancel
    held = (heavy["t"] > heavy["t"][0]) & (np.abs(heavy["alpha"] - math.radians(30.0)) < 2 * DEADBAND + 5e-4)
    assert held.any()
    origin_s = read_run_description(bag).clock_origin_ns * 1e-9  # (state stamps: origin + simulated time)
    assert heavy["u"][heavy["t"] <= trajectories_s - origin_s][-1] == 0.0
    # every kind of path was there: the goals' quintics from the setpoint, trajectories (cubic from
    # the setpoint, linear from their own first point, an empty one holding the boom), joint commands
    kinds = {
        (p.start, len(p.trajectory.points[0].velocities), len(p.trajectory.points[0].accelerations)) for p in paths
    }
    own, setpoint, boom = SetpointPath.START_OWN, SetpointPath.START_SETPOINT, SetpointPath.START_BOOM
    assert {(setpoint, 1, 1), (setpoint, 1, 0), (own, 0, 0), (boom, 0, 0), (setpoint, 0, 0)} <= kinds, kinds
    assert {p.trajectory.header.frame_id for p in paths} == {""}  # joint values, in no frame
    # the bag reads back in independent readers (MCAP with CRCs, rosbags from the bag's own
    # definitions), every path the node published there once
    counts = check_bag(bag)
    assert counts["/boom_sim/setpoint_path"] == len(paths), counts


def _trajectories_and_joint_commands(client, mover: Mover, paths: list[SetpointPath]) -> None:
    """After the goals of the closed-loop run: joint trajectories (cubic, its first point later than
    now; linear, its first point now; empty, a hold), then joint commands (a velocity alone; a
    position stamped ahead), each waited for on ~/setpoint_path."""
    from sensor_msgs.msg import JointState

    def taken(publisher, msg, again: bool = False) -> None:
        """``msg`` sent once (``again``: at every spin, as the node takes joint commands best-effort)
        until the node took it."""
        n = len(paths)
        assert client.spin_until(lambda: publisher.get_subscription_count() > 0), "the node does not subscribe"
        publisher.publish(msg)
        assert client.spin_until(lambda: len(paths) > n or (again and publisher.publish(msg))), "no ~/setpoint_path"

    cubic = _trajectory([(0.3, math.radians(35.0)), (0.8, math.radians(40.0))])
    for point, rate in zip(cubic.points, (0.2, 0.0)):
        point.velocities = [rate]
    taken(mover.trajectories, cubic)
    client.spin_sim(0.5)
    taken(mover.trajectories, _trajectory([(0.0, math.radians(38.0)), (0.4, math.radians(33.0))]))
    client.spin_sim(0.3)
    taken(mover.trajectories, JointTrajectory(joint_names=["boom_joint"]))
    client.spin_sim(0.3)
    commands = client.node.create_publisher(
        JointState, "/joint_commands", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
    )
    taken(commands, JointState(name=["boom_joint"], velocity=[0.1]), again=True)
    client.spin_sim(0.2)
    ahead = JointState(name=["boom_joint"], position=[math.radians(31.0)])
    at_ns = round((client.sim_s() + 0.2) * 1e9)  # (0.2 s after the newest state's instant, on its clock)
    ahead.header.stamp.sec, ahead.header.stamp.nanosec = divmod(at_ns, 1_000_000_000)
    taken(commands, ahead, again=True)
    client.spin_sim(0.6)
