"""Position goals for the node: the MoveBoom action and the ~/joint_trajectory topic.

Both hand the valve to the position controller (:meth:`CommandedDrive.follow`), as
ros2_control's joint_trajectory_controller drives a joint:

- ``~/joint_trajectory`` (trajectory_msgs/JointTrajectory) for ``boom_joint``: the boom
  follows its points (positions with times from start; linear between them, or cubic where
  every point has a velocity), starting from where it is, at the header stamp (zero: now).
  After the last point it holds the last position. An empty trajectory holds the boom where
  it is. A new trajectory replaces the running one, and preempts a MoveBoom goal.
- ``~/move_boom`` (boom_hydraulics_msgs/MoveBoom): a quintic move to the target at up to the
  goal's speed; the goal succeeds once the move has ended and the controller's dead-band
  holds the boom, and the boom stays held. A new goal preempts the running one; cancel
  stops the boom and closes the valve; a goal outside the stroke is rejected, with the
  reason in the node's log.
- A valve command that applies while either runs takes over (operator override): the goal
  is aborted with that reason, a trajectory is dropped with a warning.

Each path the controller starts to follow goes out once on ``~/setpoint_path`` and into the
bag (:meth:`Plant.follow`), its knots on whole nanoseconds from the instant taken, so that
boom-resim follows the same path, bit for bit.

The node's loop thread calls :meth:`Motion.after_steps` after every batch of steps, which
finishes goals. The action server lives on a hidden helper node (``_<node>_move_boom``, its
action named after the main node: ``/boom_sim/move_boom``) with a small multi-threaded
executor of its own, in which a goal's execute callback waits for that. The main node keeps
its single-threaded executor: rclpy's coroutine callbacks would poll while they wait, and a
multi-threaded executor for the whole node costs about 0.5 ms per callback (measured: a
200 Hz /clock took 100 % of a core that way, 41 % single-threaded). The helper node keeps
wall time: goal status stamps are wall time also under use_sim_time. Its services keep up
to 1000 requests waiting (rclpy's default is 10), so a burst of goals is answered goal by
goal; a client that sends such bursts needs as deep a queue of its own.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from boom_hydraulics_msgs.action import MoveBoom

from ..bags.encoding import START_BOOM, START_OWN, START_SETPOINT
from ..model.geometry import outside_stroke
from ..model.setpoints import SetpointPath, move, on_whole_ns
from ..solve.command_queue import CommandedDrive
from ..solve.simulation import Simulator

#: A goal that has not settled this long after its planned end is aborted (MoveBoom timeout_s = 0).
DEFAULT_TIMEOUT_S = 5.0
#: Feedback of a running goal, in ticks of the node's loop (every 10 ms by default: 10 Hz).
FEEDBACK_EVERY_TICKS = 10

SUCCEEDED, ABORTED, CANCELED = "succeeded", "aborted", "canceled"
#: The action's services keep this many requests waiting (rclpy's default keeps 10).
SERVICE_QUEUE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


@dataclass
class Goal:
    """A MoveBoom goal the node is working on."""

    handle: ServerGoalHandle
    target_rad: float
    started_s: float  # simulated time at acceptance
    end_s: float  # the planned move's end, simulated time
    deadline_s: float
    energy_j: float  # supply energy at acceptance
    done: threading.Event = field(default_factory=threading.Event)
    outcome: tuple[str, Any] | None = None  # (SUCCEEDED/ABORTED/CANCELED, MoveBoom.Result) once done
    ticks: int = 0


@dataclass(frozen=True)
class Plant:
    """What position goals need of the node: the drive they hand the valve to, the lock that
    guards it, the simulation (its time and outputs), the log, whether the node stops, whether
    the simulation has failed, how a stamp maps to simulated time, and how it tells of a path
    the controller starts to follow (:meth:`follow`: every goal, trajectory and joint command
    hands the valve over through it)."""

    lock: threading.RLock
    sim: Simulator
    drive: CommandedDrive
    logger: RcutilsLogger
    stopping: threading.Event
    failure: Callable[[], str | None]
    stamp_to_sim_time: Callable[[Any], float | None]
    # tells (publishes on ~/setpoint_path, records) a path the controller starts to follow now,
    # with where its first knot came from (bags.encoding.START_OWN, START_SETPOINT or START_BOOM:
    # boom_hydraulics_msgs/SetpointPath.start)
    announce: Callable[[SetpointPath, int], None]

    def follow(self, path: SetpointPath, start: int) -> SetpointPath:
        """Hand the valve to the controller along ``path``, its knots put on whole nanoseconds
        from now (so that boom-resim rebuilds it bit for bit from ~/setpoint_path), and tell of
        it; returns the path followed. ``start``: where its first knot came from."""
        path = on_whole_ns(path, self.sim.t)
        self.drive.follow(path)
        self.announce(path, start)
        return path


class Motion:
    """The node's position interfaces (see the module docstring). The node wires
    :meth:`on_trajectory` to ``~/joint_trajectory`` and :meth:`on_override` to the drive."""

    def __init__(self, plant: Plant, node_name: str, namespace: str) -> None:
        """``node_name``, ``namespace``: the main node's (the action is named after it)."""
        self.plant = plant
        self.goal: Goal | None = None  # the goal that drives the valve
        self._accepted: dict[int, Goal] = {}  # by id of the goal handle, until its execute callback takes it
        self.trajectory = False  # a ~/joint_trajectory drives the valve
        self.action_node = Node(  # the process's --ros-args (params, use_sim_time) are the main node's
            f"_{node_name}_move_boom",
            namespace=namespace,
            use_global_arguments=False,
            start_parameter_services=False,
        )
        self.server = ActionServer(
            self.action_node,
            MoveBoom,
            f"{namespace.rstrip('/')}/{node_name}/move_boom",
            execute_callback=self._execute,
            goal_callback=self._on_goal,
            handle_accepted_callback=self._on_accepted,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
            # one request at a time, in the order they arrive: in a reentrant group the executor's
            # two threads took two goals of a burst side by side, and the one accepted last (which
            # preempts the other) need not be the one sent last. Execute callbacks run as tasks
            # outside the group, so a goal waiting for its end holds none of it.
            callback_group=MutuallyExclusiveCallbackGroup(),
            # a burst of goals (each preempting the one before) must not overflow the services'
            # default queue of 10 requests, or the clients wait for answers that never come
            goal_service_qos_profile=SERVICE_QUEUE,
            result_service_qos_profile=SERVICE_QUEUE,
            cancel_service_qos_profile=SERVICE_QUEUE,
        )

    def spin_in_background(self) -> threading.Thread:
        """Serve the action from a thread of its own until the context shuts down."""
        executor = MultiThreadedExecutor(num_threads=2)
        executor.add_node(self.action_node)

        def spin() -> None:
            try:
                executor.spin()
            except Exception:  # shutting down (ExternalShutdownException, or a context gone)
                pass

        thread = threading.Thread(target=spin, name="boom_sim_move_boom", daemon=True)
        thread.start()
        self._spinning = (executor, thread)
        return thread

    def destroy(self) -> None:
        """Stop serving the action, then destroy it: the executor's thread must be out of its
        wait first (destroying the action server under a waiting executor crashed the process,
        seen as a SIGSEGV at shutdown after two signals)."""
        spinning = getattr(self, "_spinning", None)
        if spinning is not None:
            executor, thread = spinning
            try:
                executor.shutdown(timeout_sec=5.0)
            except Exception:  # the context is already gone: the thread leaves its wait by itself
                pass
            thread.join(timeout=5.0)
        self.server.destroy()
        self.action_node.destroy_node()

    # --- goals ----------------------------------------------------------------------------
    def _refusal(self, target_rad: float, speed_rad_s: float, timeout_s: float) -> str | None:
        """Why a goal cannot be taken, or None."""
        p = self.plant.sim.params
        if p.mode != "physical":
            return "position control needs mode: physical (paper mode's valve only lifts)"
        if self.plant.failure():
            return f"the simulation stopped ({self.plant.failure()}); call ~/reset first"
        if not all(math.isfinite(x) for x in (target_rad, speed_rad_s, timeout_s)):
            return "target_angle_rad, max_speed_rad_s and timeout_s must be finite"
        if speed_rad_s < 0.0 or timeout_s < 0.0:
            return "max_speed_rad_s and timeout_s must not be negative"
        return outside_stroke(p, target_rad)

    def _on_goal(self, request: MoveBoom.Goal) -> GoalResponse:
        with self.plant.lock:
            why = self._refusal(request.target_angle_rad, request.max_speed_rad_s, request.timeout_s)
        if why is not None:
            self.plant.logger.warning(f"MoveBoom goal rejected: {why}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_accepted(self, handle: ServerGoalHandle) -> None:
        plant = self.plant
        request = handle.request
        with plant.lock:
            self._finish(ABORTED, "preempted by a newer MoveBoom goal")
            self._drop_trajectory("preempted by a MoveBoom goal")
            p, sim = plant.sim.params, plant.sim
            why = self._refusal(request.target_angle_rad, request.max_speed_rad_s, request.timeout_s)
            if why is not None:  # things changed since the goal was accepted (a failure, a new mode)
                energy = 0.0 if plant.failure() else float(sim.outputs()["supply_energy"])
                self.goal = Goal(handle, request.target_angle_rad, sim.t, sim.t, sim.t, energy)
                self._accepted[id(handle)] = self.goal
                self._finish(ABORTED, why)
                handle.execute()
                return
            speed = request.max_speed_rad_s or p.control_max_speed_rad_s
            angle, rate = plant.drive.setpoint()
            path = plant.follow(move(sim.t, angle, rate, request.target_angle_rad, speed), START_SETPOINT)
            end_s = float(path.end_s[0])
            timeout = request.timeout_s or DEFAULT_TIMEOUT_S
            self.goal = Goal(
                handle, request.target_angle_rad, sim.t, end_s, end_s + timeout, plant.sim.outputs()["supply_energy"]
            )
            self._accepted[id(handle)] = self.goal
            plant.logger.info(
                f"MoveBoom: {math.degrees(angle):.2f} -> {math.degrees(request.target_angle_rad):.2f} deg "
                f"at up to {speed:g} rad/s, planned {end_s - sim.t:.2f} s"
            )
        handle.execute()

    def _execute(self, handle: ServerGoalHandle) -> MoveBoom.Result:
        """Wait (in an executor thread) until the loop finishes the goal; report how it ended."""
        with self.plant.lock:
            goal = self._accepted.pop(id(handle))
        while not goal.done.wait(0.5):
            if self.plant.stopping.is_set():
                with self.plant.lock:
                    if self.goal is goal:
                        self._finish(ABORTED, "the node is shutting down")
        outcome, result = goal.outcome
        try:
            {SUCCEEDED: handle.succeed, ABORTED: handle.abort, CANCELED: handle.canceled}[outcome]()
        except Exception:
            # a signal shut the context down under a running goal: the goal's state is set, but
            # its status can no longer be published (rclpy raises), and no client can be told
            if not self.plant.stopping.is_set():
                raise
        return result

    def _finish(self, outcome: str, message: str) -> None:
        """End the running goal (caller holds the node's lock)."""
        goal, self.goal = self.goal, None
        if goal is None:
            return
        out = self.plant.sim.outputs() if self.plant.failure() is None else None
        result = MoveBoom.Result(message=message, duration_s=self.plant.sim.t - goal.started_s)
        if out is not None:
            result.final_error_rad = goal.target_rad - float(out["alpha"])
            result.supply_energy_j = float(out["supply_energy"]) - goal.energy_j
        text = f"MoveBoom {outcome}: {message} (error {math.degrees(result.final_error_rad):.3f} deg)"
        if outcome == SUCCEEDED:  # (rclpy fixes a call site's severity: one call per level)
            self.plant.logger.info(text)
        else:
            self.plant.logger.warning(text)
        goal.outcome = (outcome, result)
        goal.done.set()

    # --- trajectories ---------------------------------------------------------------------
    def on_trajectory(self, msg: JointTrajectory) -> None:
        plant = self.plant
        with plant.lock:
            why, path, start = self._plan_trajectory(msg)
            if why is not None or path is None:
                plant.logger.warning(f"joint trajectory ignored: {why}")
                return
            self._finish(ABORTED, "preempted by a joint trajectory")
            plant.follow(path, start)
            self.trajectory = True

    def _plan_trajectory(self, msg: JointTrajectory) -> tuple[str | None, SetpointPath | None, int]:
        """(why it is ignored or None, the path to follow, where its first knot comes from)."""
        plant = self.plant
        p, sim = plant.sim.params, plant.sim
        if p.mode != "physical":
            return "position control needs mode: physical", None, START_OWN
        if plant.failure():
            return f"the simulation stopped ({plant.failure()}); call ~/reset first", None, START_OWN
        angle, rate = plant.drive.setpoint()
        if not msg.points:  # JTC: an empty trajectory stops where the boom is
            return None, SetpointPath.of([sim.t], [float(plant.sim.outputs()["alpha"])]), START_BOOM
        if "boom_joint" not in msg.joint_names:
            return f"it names {list(msg.joint_names)}; this node drives boom_joint", None, START_OWN
        j = list(msg.joint_names).index("boom_joint")
        stamp = msg.header.stamp
        start = plant.stamp_to_sim_time(stamp)
        start = sim.t if start is None else max(start, sim.t)
        times = [start + pt.time_from_start.sec + pt.time_from_start.nanosec * 1e-9 for pt in msg.points]
        try:
            positions = [float(pt.positions[j]) for pt in msg.points]
        except IndexError:
            return "a point has fewer positions than joint_names", None, START_OWN
        with_rates = all(len(pt.velocities) == len(msg.joint_names) for pt in msg.points)
        rates = [float(pt.velocities[j]) for pt in msg.points] if with_rates else None
        if not all(math.isfinite(x) for x in positions + (rates or [])):
            return "positions and velocities must be finite", None, START_OWN
        if any(b <= a for a, b in itertools.pairwise(times)) or times[0] < start:
            return "time_from_start must be non-negative and strictly increasing", None, START_OWN
        outside = [why for x in positions if (why := outside_stroke(p, x, "position")) is not None]
        if outside:
            return outside[0], None, START_OWN
        start_from = START_OWN
        if times[0] > sim.t:  # from where the setpoint is now to the first point
            start_from = START_SETPOINT
            times, positions = [sim.t, *times], [angle, *positions]
            rates = [rate, *rates] if rates is not None else None
        plant.logger.info(
            f"joint trajectory: {len(msg.points)} points over {times[-1] - sim.t:.2f} s "
            f"({'cubic' if rates is not None else 'linear'})"
        )
        return None, SetpointPath.of(times, positions, rates), start_from

    def _drop_trajectory(self, why: str) -> None:
        if self.trajectory:
            self.trajectory = False
            self.plant.logger.warning(f"joint trajectory aborted: {why}")

    # --- from the drive and the loop ------------------------------------------------------
    def on_override(self) -> None:
        """A valve command took the valve from the controller (caller holds the lock)."""
        self._finish(ABORTED, "operator override: a valve command arrived on valve_command")
        self._drop_trajectory("operator override: a valve command arrived on valve_command")

    def stop(self, why: str) -> None:
        """Reset, failure or shutdown: end what runs (caller holds the lock)."""
        self._finish(ABORTED, why)
        self._drop_trajectory(why)

    def after_steps(self) -> None:
        """After the loop's steps (caller holds the lock): feedback, cancel, success, timeout."""
        goal, plant = self.goal, self.plant
        if goal is None:
            return
        if plant.failure() is not None:
            self.stop(f"the simulation stopped: {plant.failure()}")
            return
        if goal.handle.is_cancel_requested:
            plant.drive.let_go()
            self._finish(CANCELED, "canceled: the valve is closed and the load-holding valve holds the boom")
            return
        t = plant.sim.t
        loop = plant.drive.loop
        if loop is None:  # (the override already finished it)
            return
        if t >= goal.end_s and plant.drive.holding:
            self._finish(SUCCEEDED, "settled: the boom holds the target")
            return
        if t > goal.deadline_s:
            self._finish(ABORTED, f"not settled {goal.deadline_s - goal.end_s:g} s after the planned end of the move")
            return
        goal.ticks += 1
        if goal.ticks % FEEDBACK_EVERY_TICKS == 0:
            alpha = float(plant.sim.outputs()["alpha"])
            feedback = MoveBoom.Feedback(
                angle_rad=alpha, setpoint_rad=plant.drive.setpoint()[0], error_rad=goal.target_rad - alpha
            )
            goal.handle.publish_feedback(feedback)
