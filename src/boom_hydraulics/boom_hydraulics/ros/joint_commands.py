"""Joint commands as ros2_control's JointState topic hardware interface sends them.

``joint_state_topic_hardware_interface/JointStateTopicSystem`` (ros-controls'
topic_based_hardware_interfaces, formerly PickNik's topic_based_ros2_control) publishes, at
every update of the controller manager, a sensor_msgs/JointState with its joints' names and,
per command interface, ``position[]`` and ``velocity[]`` (stamped with the controller
manager's time); it reads the joints' states from a JointState topic. This node is the plant
behind it: ``joint_commands`` in, ``joint_states`` out. A command for ``boom_joint`` becomes a
setpoint of the position controller (model/control.py), as a MoveBoom goal or a trajectory
does:

- *position* (rad): the setpoint angle, held until the next command (rate 0 without a
  velocity: the controller's PI drives the boom there, and its dead-band holds it);
- *velocity* (rad/s) with a position: the setpoint's rate from there on; the feedforward
  opens the valve for the rod speed that gives it (the boom rate over the lever
  d(alpha)/dq1 at the present cylinder length, against the static load), the PI corrects;
- *velocity* alone: the boom turns at that rate. The setpoint goes on from where it is (from
  the boom's angle when the controller was not following joint commands, and never more than
  :data:`MAX_LEAD_RAD` ahead of the boom, so that a rate the drive cannot give does not wind
  the setpoint up), and the feedforward and PI make the rod follow at the speed the lever asks.

A rate carries the setpoint on for ``command_timeout_s`` (as a valve command holds that long;
0: until the stroke's end), then the setpoint stops where it got to and the boom is held
there: a velocity command must be renewed, as the hardware interface does at every update.
The setpoint stops at the stroke's ends. A command acts at its stamp by the node's rule (zero
or past: at once; future: at its stamp; older than ``command_timeout_s`` when it arrives:
stale, ignored). It preempts a MoveBoom goal or a trajectory; a valve command overrides it.
Ignored with a throttled warning: no ``boom_joint`` among the names, neither a position nor a
velocity for it, a value that is not finite, a position outside the stroke, paper mode, a
stopped simulation.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable

from sensor_msgs.msg import JointState

from ..bags.encoding import START_OWN, START_SETPOINT
from ..model.geometry import outside_stroke, stroke_angles_rad
from ..model.robot_description import JOINTS
from ..model.setpoints import SetpointPath
from ..solve.command_queue import stale
from .clock import NodeClock
from .motion import Plant

#: The joint this node drives.
JOINT = JOINTS[0]
#: How far a velocity-only command's setpoint may start ahead of (or behind) the boom, rad.
MAX_LEAD_RAD = 0.05


def read_command(msg: JointState) -> tuple[str | None, float | None, float | None]:
    """(why it is ignored or None, the position or None, the velocity or None) of ``boom_joint``
    in ``msg``: its values at the index of its name, in the arrays that have one per name."""
    names = list(msg.name)
    if JOINT not in names:
        return f"it names {names}; this node drives {JOINT}", None, None
    i = names.index(JOINT)
    values: list[float | None] = []
    for field, array in (("position", msg.position), ("velocity", msg.velocity)):
        if len(array) not in (0, len(names)):
            return f"{field} has {len(array)} values for {len(names)} names", None, None
        value = float(array[i]) if array else None
        if value is not None and not math.isfinite(value):
            return f"{field} {value} of {JOINT} is not finite", None, None
        values.append(value)
    position, velocity = values
    if position is None and velocity is None:
        return f"neither a position nor a velocity for {JOINT}", None, None
    return None, position, velocity


def angle_before(path: SetpointPath, t_s: float) -> float:
    """The angle of ``path`` (one set) just before ``t_s``: where the setpoint goes on as it
    was up to a command that acts at ``t_s``. Where ``path`` steps at ``t_s`` (knots at that
    very time: a command stamped ahead, as the hardware interface repeats it), the angle it
    steps from, not the one it steps to: :meth:`SetpointPath.at` gives the latter there, and
    a repeated command stamped ahead would ramp from now to its angle instead of holding."""
    times, angles = path.times_s[:, 0].tolist(), path.angles_rad[:, 0].tolist()
    i = bisect.bisect_left(times, t_s)
    if i < len(times) and times[i] == t_s:
        return angles[i]  # (a segment ends at its knot's angle; before the first knot it holds that)
    return path.at(t_s)[0]


class JointCommands:
    """The ``joint_commands`` topic of one node (callers hold the node's lock)."""

    def __init__(self, plant: Plant, clock: NodeClock, preempt: Callable[[str], None]) -> None:
        """``preempt(why)`` ends a running MoveBoom goal or trajectory (:meth:`Motion.stop`)."""
        self.plant, self.clock, self.preempt = plant, clock, preempt
        self.path: SetpointPath | None = None  # the path of the last command taken

    @property
    def driving(self) -> bool:
        """Whether the controller follows the joint commands now (no goal, trajectory or
        valve command has taken over since the last one)."""
        loop = self.plant.drive.loop
        return self.path is not None and loop is not None and loop.path is self.path

    def on_message(self, msg: JointState) -> None:
        why = self._take(msg)
        if why is not None:
            self.plant.logger.warning(f"joint command ignored: {why}", throttle_duration_sec=1.0)

    def _take(self, msg: JointState) -> str | None:
        """Follow the command in ``msg``; why not, if it is ignored."""
        plant = self.plant
        p, sim, drive = plant.sim.params, plant.sim, plant.drive
        why, position, velocity = read_command(msg)
        if why is not None:
            return why
        if p.mode != "physical":
            return "position control needs mode: physical"
        if plant.failure():
            return f"the simulation stopped ({plant.failure()}); call ~/reset first"
        if position is not None and (outside := outside_stroke(p, position, "position")) is not None:
            return outside
        at = self.clock.stamp_to_sim_time(msg.header.stamp)
        if at is not None:
            received_s = self.clock.received_s()
            if stale(at, received_s, drive.timeout_s):
                return (
                    f"stamped {received_s - at:.3f} s before it arrived: older than command_timeout_s = "
                    f"{drive.timeout_s:g} s, it is stale"
                )
        start = sim.t if at is None else max(at, sim.t)
        path = self._path(start, position, velocity or 0.0)
        if self._holds(path):
            return None  # the same hold again (as the hardware interface repeats it): the controller goes on as it is
        self.preempt("preempted by a joint command on joint_commands")
        # its first knot: the setpoint now where the command acts later, else the command's own
        # angle (or, for a velocity alone, where the setpoint was, within MAX_LEAD_RAD of the boom)
        self.path = plant.follow(path, START_SETPOINT if start > sim.t else START_OWN)
        return None

    def _holds(self, path: SetpointPath) -> bool:
        """Whether ``path`` holds the angle at which the controller already holds the joint
        commands' setpoint: then it goes on as it is (its integral and dead-band kept)."""
        held = self.path
        return (
            self.driving
            and held is not None
            and held.angles_rad.shape[0] == 1
            and path.angles_rad.shape[0] == 1
            and float(path.angles_rad[0, 0]) == float(held.angles_rad[0, 0])
        )

    def _path(self, start_s: float, position: float | None, rate: float) -> SetpointPath:
        """The setpoint from now on: as it was up to ``start_s``, then from the command's
        angle (``position``, or where the setpoint is) on at ``rate``."""
        plant = self.plant
        sim, drive = plant.sim, plant.drive
        times: list[float] = []
        angles: list[float] = []
        if self.driving and self.path is not None:
            before = angle_before(self.path, start_s)
            knots = zip(*(a[:, 0].tolist() for a in (self.path.times_s, self.path.angles_rad)))
            for t, angle in knots:  # (the knots still to come before the command: a command stamped ahead)
                if sim.t < t < start_s:
                    times.append(t)
                    angles.append(angle)
        else:
            before, _ = drive.setpoint()  # (the boom's angle, or the setpoint of a goal preempted)
        if start_s > sim.t:  # a command stamped ahead: the setpoint goes on as it was until then
            now, _ = self.path.at(sim.t) if self.driving and self.path is not None else (before, 0.0)
            times, angles = [sim.t, *times, start_s], [now, *angles, before]
        anchor = position
        if anchor is None:  # velocity alone: on from where the setpoint is, not far from the boom
            anchor = before
            if start_s <= sim.t:
                alpha = float(sim.outputs()["alpha"])
                anchor = min(max(anchor, alpha - MAX_LEAD_RAD), alpha + MAX_LEAD_RAD)
        times.append(start_s)
        angles.append(anchor)
        end = self._rate_end(start_s, anchor, rate)
        if end is not None:
            times.append(end[0])
            angles.append(end[1])
        return SetpointPath.of(times, angles)

    def _rate_end(self, start_s: float, anchor: float, rate: float) -> tuple[float, float] | None:
        """Where a setpoint from ``anchor`` at ``rate`` stops: after command_timeout_s (0:
        never) or at the stroke's end, whichever comes first; None when it does not move."""
        if rate == 0.0:
            return None
        low, high = stroke_angles_rad(self.plant.sim.params)
        limit = high if rate > 0.0 else low
        duration = (limit - anchor) / rate  # until the stroke's end
        timeout = self.plant.drive.timeout_s
        if timeout > 0.0:
            duration = min(duration, timeout)
        if duration <= 0.0:
            return None
        return start_s + duration, anchor + rate * duration
