"""ROS 2 node ``boom_sim``: the model core in a loop, driven by valve commands or position goals.

    ros2 run boom_hydraulics boom_sim --ros-args --params-file config/default.yaml
    boom_sim --help        # every parameter with its default and unit

Physics runs at ``time_step_s``, several steps per tick of ``publish_rate_hz``; simulated
time follows the steady clock by elapsed time (times ``real_time_factor``; 0 runs as fast
as possible), so a late tick catches up. With ``use_sim_time`` it follows the ROS clock
(/clock, whoever publishes it) instead: half-speed /clock, half-speed physics; a stopped
/clock, stopped physics; a clock that jumps back resets the drive to rest.

The ticks run in a thread of their own that sleeps to absolute deadlines: an rclpy timer
would wake the executor, which rebuilds its wait set in Python, 100 times a second (29 % of
a core measured, against about 10 % this way). The executor serves commands, trajectories,
services and parameters; a lock keeps the two threads from touching the simulation at
once. Commands are applied by their stamps (see :mod:`command_queue`), which makes a run
depend only on the commands and their times, not on wall-clock jitter. Position goals
(MoveBoom, ~/joint_trajectory; see :mod:`motion`) hand the valve to the model core's
position controller. Simulated time never runs backwards: a reset puts the drive back to
rest and time goes on. The node publishes its URDF on robot_description and the crane as
markers. Topics, services, the action and parameters are listed in the README.
"""

from __future__ import annotations

import functools
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import ParameterEvent, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_parameter_events,
    qos_profile_sensor_data,
)
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.time import Time
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool
from visualization_msgs.msg import MarkerArray

from boom_hydraulics_msgs.msg import DriveState, ValveCommand
from boom_hydraulics_msgs.srv import Reset, Step

from ..bags import cdr
from ..bags.encoding import parameter_event_cdr, setpoint_cdr
from ..bags.recording import BagRecorder, Topic, new_bag_folder, offered_qos, run_description
from ..errors import BoomHydraulicsError, ConfigError, SimulationError
from ..model.parameters import NAMES, from_mapping
from ..model.robot_description import JOINTS, urdf
from ..solve.command_queue import CommandedDrive, stale, valve_opening
from ..solve.pacing import Pacer
from ..solve.simulation import Simulator
from . import messages
from . import node_parameters as ros_parameters
from .markers import crane_markers
from .motion import Motion

_NODE_ATTRIBUTES = {
    "publish_rate_hz": "rate_hz",
    "real_time_factor": "rtf",
    "command_timeout_s": "timeout_s",
    "max_catch_up_s": "max_catch_up_s",
}
PARAMETER_EVENTS = "/parameter_events"
#: Markers go out at most this often (they are for eyes, not for control).
MARKERS_HZ = 20.0
#: A ROS clock that steps back by more than this is a jump back (a world reset), s.
CLOCK_JUMP_S = 1e-3
#: The most simulated time one ~/step call may take, s: the executor serves nothing else
#: meanwhile, so a larger request is refused with how to get there.
STEP_CALL_LIMIT_S = 10.0


def _type_name(msg_type: Any) -> str:
    """'pkg/msg/Type' of a generated message class."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def _locked(method: Callable) -> Callable:
    """Run an executor callback while holding the node's lock (the loop thread steps too)."""

    @functools.wraps(method)
    def wrapper(self: BoomSimNode, *args: Any) -> Any:
        with self.lock:
            return method(self, *args)

    return wrapper


def _qos_time(duration: Any) -> QosTime:
    sec, nsec = divmod(duration.nanoseconds, 1_000_000_000)
    return QosTime(sec=sec, nsec=nsec)


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


class BoomSimNode(Node):
    """Thin ROS shell around :class:`Simulator`."""

    def __init__(self) -> None:
        super().__init__("boom_sim")
        self._declare_parameters()
        self._read_node_parameters()
        params = from_mapping({name: ros_parameters.plain(self.get_parameter(name).value) for name in NAMES})
        self.publish_clock = bool(self.get_parameter("publish_clock").value)
        self.follow_clock = bool(self.get_parameter("use_sim_time").value)
        if self.follow_clock and self.publish_clock:
            raise ConfigError(
                "use_sim_time and publish_clock are both true: this node either follows /clock (use_sim_time, "
                "another node publishes it) or publishes it (publish_clock); set one of them to false"
            )
        self.sim = Simulator(params, jit=bool(self.get_parameter("jit").value))
        if self.sim.jit:  # compile (or load from the cache) the steps and the outputs before the clock starts
            self.sim.step(0.0, 0)
            self.sim.outputs()
        self.drive = CommandedDrive(self.sim, self.timeout_s)
        self.lock = threading.RLock()
        self.stopping = threading.Event()
        self.paused = bool(self.get_parameter("start_paused").value)
        self.failure: str | None = None
        self._substeps_logged = self.sim.most_substeps  # the substeps the log has told about
        # on a shared clock the backlog is worked off, never dropped: simulated time stays the clock's
        self.pacer = Pacer(self.rate_hz, self._pace_factor(), self.max_catch_up_s, drop_backlog=not self.follow_clock)

        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.state_pub = self.create_publisher(DriveState, "drive_state", state_qos)
        self.joint_pub = self.create_publisher(JointState, "joint_states", state_qos)
        self.p1_pub = self.create_publisher(FluidPressure, "piston_pressure", state_qos)
        self.p2_pub = self.create_publisher(FluidPressure, "rod_pressure", state_qos)
        self.force_pub = self.create_publisher(WrenchStamped, "rod_force", state_qos)
        self.markers_pub = self.create_publisher(MarkerArray, "~/markers", state_qos)
        self.setpoint_pub = self.create_publisher(JointState, "~/setpoint", state_qos)
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.description_pub = (
            self.create_publisher(String, "robot_description", latched)
            if self.get_parameter("publish_robot_description").value
            else None
        )
        self._markers_every = max(1, round(self.rate_hz / MARKERS_HZ))
        self._ticks = 0
        self._clock_seen_s = 0.0  # the latest ROS time the loop saw (use_sim_time)
        self._description_due = False  # a parameter change asks for robot_description again
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", state_qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", state_qos) if self.publish_clock else None
        # best-effort subscriptions accept commands from reliable and best-effort publishers;
        # raw: the bytes as received are recorded, and parsed once here
        self.command_topics = {
            self.resolve_topic_name("valve_command"): ValveCommand,
            self.resolve_topic_name("commands"): Float64MultiArray,
        }
        self.commands_received = self.commands_stale = self.commands_lost = self.commands_refused = 0
        # commands lost in a flood (the sensor-data queue keeps the last 5): gaps in a lone
        # publisher's sequence numbers (Fast DDS raises no message-lost event)
        self._sole_publisher = dict.fromkeys(self.command_topics, False)
        self._last_sequence: dict[str, int] = {}
        self.create_subscription(ValveCommand, "valve_command", self.on_command, qos_profile_sensor_data, raw=True)
        self.create_subscription(
            Float64MultiArray, "commands", self.on_command_array, qos_profile_sensor_data, raw=True
        )
        self.resets = self.pauses = self.steps_paused = 0  # calls of ~/reset, ~/pause (true), ~/step
        self.origin_shift_s = 0.0  # how far dropped backlogs moved the time origin of command stamps
        self.recording_error: str | None = None
        self.create_service(Reset, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.create_service(Step, "~/step", self.on_step)
        self.add_pre_set_parameters_callback(self.before_set_parameters)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.after_set_parameters)
        self.motion = Motion(self)

        self._restart_clock()
        # The bag starts with the stepping (its time origin, simulated time 0): at start() on
        # the node's own clock, at the first /clock on a shared one. Commands received before
        # it are kept for it.
        self.recorder: BagRecorder | None = None
        self.record_pending = bool(self.get_parameter("record").value)
        self._early_commands: list[tuple[str, bytes, dict]] = []
        self.diag_timer = self.create_timer(1.0, self.on_second)
        self.loop = threading.Thread(target=self.run_loop, name="boom_sim_loop", daemon=True)
        p = self.sim.params
        if any(getattr(p, name) != ros_parameters.default(name) for name in ros_parameters.SCENARIO):
            self.get_logger().info(
                "the command_* parameters describe boom-sim's headless scenario; this node takes "
                "its valve commands on valve_command and commands"
            )
        pace = (
            "following the ROS clock (use_sim_time)"
            if self.follow_clock
            else f"real-time factor {self.rtf:g}{' (as fast as possible)' if self.rtf == 0 else ''}"
        )
        self.get_logger().info(
            f"{p.mode} mode, {p.method} dt={p.time_step_s} s, {self.rate_hz:g} Hz, {pace}, "
            f"{'compiled' if self.sim.compiled else 'interpreted'}"
        )

    def start(self) -> None:
        """Start stepping: simulated time 0 is now (on the node's own clock; on a shared one,
        the first /clock), so that a command stamped in ROS time acts at its stamp."""
        with self.lock:
            if not self.follow_clock:
                self._restart_clock()
                self._begin_recording()
            self.publish_description()
        self.loop.start()

    def _begin_recording(self) -> None:
        """Open the bag, if asked for, at the time origin, with the commands received before it."""
        if not self.record_pending:
            return
        self.record_pending = False
        self.recorder = self._start_recording()
        for topic, data, info in self._early_commands:
            self._record_received(topic, data, info)
        self._early_commands.clear()

    # --- parameters -----------------------------------------------------------------------
    def _declare_parameters(self) -> None:
        """Declare every parameter, typed (an integer for a float is taken as that float),
        after refusing keys for this node that name no parameter."""
        overrides = self._parameter_overrides  # rclpy: this node's values from files and -p
        ros_parameters.check_known(overrides)
        for name in overrides:
            overrides[name] = ros_parameters.typed(overrides[name])
        # our checks first: they name the unit and the fix, where rclpy's range check does not
        from_mapping({name: ros_parameters.plain(p.value) for name, p in overrides.items() if name in NAMES})
        for name, p in overrides.items():
            if name in ros_parameters.NODE_PARAMETERS:
                ros_parameters.check_node_parameter(name, p.value)
        for name in ros_parameters.all_names():
            self.declare_parameter(name, ros_parameters.default(name), ros_parameters.descriptor(name))

    def _read_node_parameters(self) -> None:
        self.rate_hz = float(self.get_parameter("publish_rate_hz").value)
        self.rtf = float(self.get_parameter("real_time_factor").value)
        self.timeout_s = float(self.get_parameter("command_timeout_s").value)
        self.max_catch_up_s = float(self.get_parameter("max_catch_up_s").value)

    def before_set_parameters(self, changes: list[Parameter]) -> list[Parameter]:
        """An integer for a float parameter becomes that float, before rclpy checks the type."""
        return [ros_parameters.typed(p) for p in changes]

    def on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Validate a change as a whole (cross-field checks too); refuse it with the reason.
        A new method or mode is compiled (or loaded) first, while the loop goes on stepping,
        so that applying it holds the loop up for no longer than a tick."""
        with self.lock:
            refusal, new_params = self._check_changes(changes)
        if refusal is not None:
            return refusal
        current = self.sim.params
        if (
            new_params is not None
            and self.sim.jit
            and (new_params.mode, new_params.method)
            != (
                current.mode,
                current.method,
            )
        ):
            warm = Simulator(new_params, jit=True)
            warm.step(0.0, 0)
            warm.outputs()
        with self.lock:
            return self._apply_changes(changes, new_params)

    def _check_changes(self, changes: list[Parameter]) -> tuple[SetParametersResult | None, Any]:
        """(a refusal or None, the model parameters after the change or None)."""
        model_changes = {p.name: ros_parameters.plain(p.value) for p in changes if p.name in NAMES}
        node_changes = {p.name: p.value for p in changes if p.name in ros_parameters.NODE_PARAMETERS}
        for p in changes:
            if p.name == "use_sim_time" and bool(p.value) != self.follow_clock:
                reason = (
                    "use_sim_time is start-only: the clock a run follows is chosen when it starts; "
                    "restart the node with -p use_sim_time:=" + ("true" if p.value else "false")
                )
                return SetParametersResult(successful=False, reason=reason), None
        try:
            for name, value in node_changes.items():
                ros_parameters.check_node_parameter(name, value)
            new_params = from_mapping(model_changes, base=self.sim.params) if model_changes else None
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc)), None
        return None, new_params

    def _apply_changes(self, changes: list[Parameter], new_params: Any) -> SetParametersResult:
        """Apply a checked change (the caller holds the lock)."""
        node_changes = {p.name: p.value for p in changes if p.name in ros_parameters.NODE_PARAMETERS}
        dt_before = self.sim.params.time_step_s
        if new_params is not None:
            if new_params.mode != "physical":
                self.motion.stop("mode changed to paper, which has no position control")
            self.sim.set_parameters(new_params)
            self.drive.parameters_changed()
            self._description_due = True
        if node_changes:
            self.get_logger().info(f"node parameters changed: {node_changes}")
            for name, value in node_changes.items():  # rclpy stores them after this returns
                setattr(self, _NODE_ATTRIBUTES[name], float(value))
            self.drive.timeout_s = self.timeout_s  # the drive applies it
            self.pacer.rate_hz, self.pacer.real_time_factor = self.rate_hz, self._pace_factor()
            self._markers_every = max(1, round(self.rate_hz / MARKERS_HZ))
            self.pacer.max_catch_up_s = self.max_catch_up_s
        if "real_time_factor" in node_changes:
            self._restart_clock()  # a new pace: simulated time follows the clock afresh from here
        elif new_params is not None or node_changes:
            # the time origin stays: the change takes no simulated time
            self.pacer.rebase(self.sim.step_count, dt_before)
        # the node-clock time of the simulated instant the change takes effect at
        self._changed_at_ns = self._sim_instant_ns()
        return SetParametersResult(successful=True)

    def after_set_parameters(self, changes: list[Parameter]) -> None:
        """Record the change as rclpy announces it on /parameter_events, stamped with the
        node-clock time of the simulated instant it took effect at (boom-resim applies it there);
        publish the robot description again when a dimension changed."""
        if self._description_due:
            self._description_due = False
            self.publish_description()
        if self.recorder is None:
            return
        changed = [(p.name, p.type_.value, ros_parameters.plain(p.value)) for p in changes]
        data = parameter_event_cdr(self.get_fully_qualified_name(), self._changed_at_ns, changed)
        self.recorder.write(PARAMETER_EVENTS, self._now_ns(), data)

    # --- recording ------------------------------------------------------------------------
    def _start_recording(self) -> BagRecorder:
        """A bag of every topic this node publishes, its parameter changes, and every command
        it receives (each command topic once its first publisher shows up)."""
        pubs = [self.state_pub, self.joint_pub, self.p1_pub, self.p2_pub, self.force_pub, self.diag_pub]
        pubs += [self.markers_pub, self.setpoint_pub]
        pubs += [pub for pub in (self.description_pub, self.clock_pub) if pub is not None]
        topics = [Topic(p.topic_name, _type_name(p.msg_type), (offer_of(p.qos_profile),)) for p in pubs]
        events_qos = offered_qos(depth=qos_profile_parameter_events.depth)
        topics.append(Topic(PARAMETER_EVENTS, _type_name(ParameterEvent), (events_qos,)))
        recorder = BagRecorder(
            new_bag_folder(self.get_parameter("record_folder").value, self.get_fully_qualified_name()),
            topics,
            chunk_size=round(self.get_parameter("record_chunk_kib").value * 1024),
            custom_data=run_description(
                self.sim.params, self._origin_ns(), self.rate_hz, self.timeout_s, node=self.get_fully_qualified_name()
            ),
            flush_s=float(self.get_parameter("record_flush_s").value),
        )
        self.get_logger().info(f"recording to {recorder.folder}")
        return recorder

    def _origin_ns(self) -> int:
        return self.clock_origin_ns

    def _sim_instant_ns(self) -> int:
        """The node-clock time of the simulated instant now (integer ns: float seconds of the
        epoch would round it to a quarter of a microsecond)."""
        return self.clock_origin_ns + round(self.sim.t * 1e9)

    def _offers(self, topic: str) -> tuple[Qos, ...]:
        """What the publishers of ``topic`` offer (as ``ros2 bag record`` records it)."""
        return tuple(offer_of(info.qos_profile) for info in self.get_publishers_info_by_topic(topic))

    def _watch_command_topics(self) -> None:
        """Declare a command topic once it has a publisher; keep its offers up to date."""
        for topic, msg_type in self.command_topics.items():
            offers = self._offers(topic)
            if offers and topic not in self.recorder.topics:
                self.recorder.add_topic(Topic(topic, _type_name(msg_type), offers))
            self.recorder.add_offers(topic, offers)

    def _record_received(self, topic: str, data: bytes, info: dict) -> None:
        """Log a received command at its receive time on the node's clock, as rosbag2 does
        (its header stamp stays inside the message); publish time: when it was sent."""
        if self.record_pending:
            self._early_commands.append((topic, data, info))
            return
        if self.recorder is None:
            return
        if topic not in self.recorder.topics:
            offers = self._offers(topic) or (offered_qos(),)
            self.recorder.add_topic(Topic(topic, _type_name(self.command_topics[topic]), offers))
        received = self._now_ns()
        self.recorder.write(topic, received, data, info.get("source_timestamp") or received)

    def _publish(self, messages: list[tuple[Any, Any]], log_ns: int) -> None:
        """Publish (publisher, message) pairs, then record them all: a tick cut short by
        shutdown leaves no partial tick in the bag. While recording, each message is
        serialised once, and the bytes published are the bytes recorded. A message given as
        CDR bytes is published and recorded as those bytes."""
        if self.recorder is None:
            for publisher, msg in messages:
                publisher.publish(msg)
            return
        serialised = [
            (publisher, msg if isinstance(msg, bytes) else serialize_message(msg)) for publisher, msg in messages
        ]
        for publisher, data in serialised:
            publisher.publish(data)
        for publisher, data in serialised:
            self.recorder.write(publisher.topic_name, log_ns, data)

    # --- commands -------------------------------------------------------------------------
    def stamp_to_sim_time(self, stamp: Any) -> float | None:
        """Simulated time a command stamp means; None for a zero (unset) stamp."""
        if stamp.sec == 0 and stamp.nanosec == 0:
            return None
        return (stamp.sec * 1_000_000_000 + stamp.nanosec - self.clock_origin_ns) * 1e-9

    def _accept(self, opening: float, stamp: Any | None) -> None:
        u = valve_opening(opening, self.sim.params.mode)
        if u is None:
            self.get_logger().warning(f"ignored non-finite valve opening {opening}", throttle_duration_sec=1.0)
            return
        if u != opening:
            self.get_logger().warning(f"valve opening {opening} clamped to {u:g}", throttle_duration_sec=1.0)
        self.commands_received += 1
        at = self.stamp_to_sim_time(stamp) if stamp is not None else None
        if at is not None:
            received_s = (self._now_ns() - self.clock_origin_ns) * 1e-9  # by the log time the bag keeps
            if stale(at, received_s, self.timeout_s):
                self.commands_stale += 1
                self.get_logger().warning(
                    f"ignored a valve command stamped {received_s - at:.3f} s before it arrived: older than "
                    f"command_timeout_s = {self.timeout_s:g} s, it is stale; stamp commands with the time they are "
                    "meant for (a zero stamp: now), or raise command_timeout_s",
                    throttle_duration_sec=1.0,
                )
                return
        if not self.drive.push(self.sim.t if at is None else at, u):
            self.commands_refused += 1
            self.get_logger().warning("too many future-stamped commands waiting; refused", throttle_duration_sec=1.0)

    def _count_lost(self, topic: str, info: dict) -> None:
        """Count the commands a lone publisher sent that never reached this node."""
        sequence = info.get("publication_sequence_number")
        if not sequence or not self._sole_publisher[topic]:
            return
        last = self._last_sequence.get(topic)
        if last is not None and sequence > last + 1:
            self.commands_lost += sequence - last - 1
        self._last_sequence[topic] = sequence

    def _watch_publishers(self) -> None:
        """Once a second: which command topics have one publisher (whose gaps are losses)."""
        for topic in self.command_topics:
            sole = self.count_publishers(topic) == 1
            if sole != self._sole_publisher[topic]:
                self._sole_publisher[topic] = sole
                self._last_sequence.pop(topic, None)

    @_locked
    def on_command(self, data: bytes, info: dict) -> None:
        topic = self.resolve_topic_name("valve_command")
        self._record_received(topic, data, info)
        self._count_lost(topic, info)
        msg = deserialize_message(data, ValveCommand)
        self._accept(msg.opening, msg.header.stamp)

    @_locked
    def on_command_array(self, data: bytes, info: dict) -> None:
        topic = self.resolve_topic_name("commands")
        self._record_received(topic, data, info)
        self._count_lost(topic, info)
        msg = deserialize_message(data, Float64MultiArray)
        if len(msg.data) != 1:
            self.get_logger().warning(
                f"'commands' expects one value (the valve opening), got {len(msg.data)}", throttle_duration_sec=1.0
            )
            return
        self._accept(msg.data[0], None)

    # --- services -------------------------------------------------------------------------
    @_locked
    def on_reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        try:
            self._back_to_rest("reset (~/reset)", request.rod_position_m if request.use_rod_position else None)
        except SimulationError as exc:
            response.success, response.message = False, str(exc)
            return response
        response.success, response.message = True, f"reset to q1 = {self.sim.y[0]:.4f} m"
        self.resets += 1
        self.publish_state()
        self.publish_diagnostics()  # the bag keeps the count at once: boom-resim reads it
        return response

    @_locked
    def on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if request.data == self.paused:
            response.success, response.message = True, "already paused" if self.paused else "already running"
            return response
        self.paused = request.data
        if self.paused:
            self.pauses += 1
        else:
            self._restart_clock()
        response.success, response.message = True, "paused" if self.paused else "resumed"
        self.publish_diagnostics()  # the bag keeps the count at once: boom-resim reads it
        return response

    @_locked
    def on_step(self, request: Step.Request, response: Step.Response) -> Step.Response:
        if not self.paused:
            response.success, response.message = False, "step works while paused; call ~/pause with data: true"
        elif self.failure:
            response.success, response.message = False, f"simulation stopped: {self.failure}; call ~/reset"
        else:
            steps, dt = max(1, request.steps), self.sim.params.time_step_s
            limit = max(1, int(STEP_CALL_LIMIT_S / dt))
            if steps > limit:
                response.success = False
                response.message = (
                    f"steps: {steps} is {steps * dt:g} s of simulated time; one call takes at most "
                    f"{STEP_CALL_LIMIT_S:g} s ({limit} steps of {dt:g} s): call ~/step again for more"
                )
                response.sim_time_s = self.sim.t
                return response
            self.advance(steps)
            self.steps_paused += 1
            response.success, response.message = self.failure is None, self.failure or "ok"
            self.publish_state()
            self.publish_diagnostics()
        response.sim_time_s = self.sim.t
        return response

    # --- time and stepping ---------------------------------------------------------------------
    def _back_to_rest(self, why: str, rod_position_m: float | None = None) -> None:
        """The drive at rest (at ``rod_position_m``, default q1(0)), valve closed, goals ended
        with ``why``; simulated time runs on. Raises SimulationError for a position outside the stroke."""
        stopped = self.failure is not None
        self.sim.reset(rod_position_m, keep_time=True)
        self.motion.stop(why)
        self.drive.reset()
        self.failure = None
        if stopped:  # a stopped simulation stood still, as a paused one does: it goes on from now
            self._restart_clock()
        else:  # time runs on from here, tied to the clock as before
            self.pacer.rebase(self.sim.step_count, self.sim.params.time_step_s)

    def _pace_factor(self) -> float:
        """Simulated seconds per second of the clock followed: 1 on the ROS clock."""
        return 1.0 if self.follow_clock else self.rtf

    def _pace_clock_s(self) -> float:
        """The clock simulated time follows: the ROS clock (use_sim_time) or the steady clock."""
        if self.follow_clock:
            return self.get_clock().now().nanoseconds * 1e-9
        return time.monotonic()

    def _restart_clock(self) -> None:
        """Tie simulated time to the clock from now on: at the start (or the first /clock), a
        resume, a new real-time factor and a jump back of the ROS clock."""
        self.pacer.restart(self._pace_clock_s(), self.sim.step_count)
        # command stamps are sim time when the node owns the clock, else ROS time mapped to sim time
        now_ns = self.get_clock().now().nanoseconds
        self.clock_origin_ns = 0 if self.publish_clock else now_ns - round(self.sim.t * 1e9)
        self._clock_seen_s = now_ns * 1e-9

    def _follow_ros_clock(self) -> bool:
        """use_sim_time: whether the loop may step now. No /clock yet: wait. A jump back (a
        world reset): the drive goes back to rest, as ~/reset does, and follows the clock from there."""
        now = self.get_clock().now().nanoseconds * 1e-9
        if now <= 0.0:
            return False
        if self._clock_seen_s <= 0.0:  # the first /clock
            self._restart_clock()
            if self.record_pending:
                self._begin_recording()
                self.publish_description()  # (transient local: published again, so the bag has it)
            return True
        if now < self._clock_seen_s - CLOCK_JUMP_S:
            self.get_logger().warning(
                f"the ROS clock jumped back from {self._clock_seen_s:.3f} s to {now:.3f} s: "
                "the drive is reset to rest, as ~/reset does (simulated time runs on)"
            )
            self._back_to_rest("the ROS clock jumped back")
            self.resets += 1  # a reset as ~/reset's: boom-resim must know of it
            self._restart_clock()
            return True
        self._clock_seen_s = max(self._clock_seen_s, now)
        return True

    def advance(self, steps: int) -> None:
        """Take ``steps`` physics steps, applying queued commands at their times."""
        if self.failure is not None:
            return
        try:
            self.drive.advance(steps)
        except SimulationError as exc:
            self.failure = str(exc)
            self.get_logger().error(f"simulation stopped, waiting for ~/reset: {exc}")
        self.motion.after_steps()
        if self.sim.most_substeps > self._substeps_logged:
            self._substeps_logged = self.sim.most_substeps
            p = self.sim.params
            self.get_logger().info(
                f"stability bound: {p.method} takes {self._substeps_logged} substeps per time step of "
                f"{p.time_step_s:g} s here (the step and the outputs stay at {p.time_step_s:g} s)"
            )

    def run_loop(self) -> None:
        """Tick at ``publish_rate_hz`` of wall time (back to back at real_time_factor 0)."""
        deadline = time.monotonic()
        while not self.stopping.is_set():
            if self.rtf == 0 and not self.follow_clock:
                time.sleep(0)  # let the executor thread take commands between ticks
            else:
                deadline += 1.0 / self.rate_hz
                delay = deadline - time.monotonic()
                if delay > 0:
                    self.stopping.wait(delay)
                else:
                    deadline = time.monotonic()  # a late tick: no burst of ticks to catch up
            try:
                with self.lock:
                    self.on_tick()
            except Exception as exc:
                if not rclpy.ok():  # the context went away under us: shutting down
                    return
                with self.lock:  # anything else stops the simulation, reported like a blow-up
                    self.failure = f"tick failed: {exc!r}"
                self.get_logger().error(f"simulation stopped, waiting for ~/reset: {self.failure}")

    def on_tick(self) -> None:
        if self.paused or self.failure:
            return
        if self.follow_clock and not self._follow_ros_clock():
            return
        dt = self.sim.params.time_step_s
        tick = self.pacer.due(self._pace_clock_s(), self.sim.step_count, dt)
        if tick.dropped_s:  # cannot keep up: the pacer gave up the backlog beyond max_catch_up_s
            behind_s = tick.steps * dt / self.pacer.real_time_factor + tick.dropped_s
            self.get_logger().warning(
                f"{behind_s:.3f} s behind {'the ROS clock' if self.follow_clock else 'real time'}; "
                "dropping the backlog",
                throttle_duration_sec=5.0,
            )
            if not self.publish_clock:
                self.clock_origin_ns += round(tick.dropped_s * 1e9)  # ROS-time stamps map to the later sim time
                self.origin_shift_s += tick.dropped_s
        if tick.steps <= 0:
            return
        if self.follow_clock:
            self._advance_publishing(tick.steps, self.pacer.per_tick(dt))
        else:
            self.advance(tick.steps)
            if self.failure is None:
                self.publish_state()
        self.pacer.settled(self.sim.step_count, dt)
        self._watch_recorder()

    def _advance_publishing(self, steps: int, per_tick: int) -> None:
        """Take ``steps`` steps, publishing at every multiple of ``per_tick`` steps: on a shared
        clock the states come at publish_rate_hz of the clock's time, whatever its pace."""
        while steps > 0 and self.failure is None:
            n = min(steps, per_tick - self.sim.step_count % per_tick)
            self.advance(n)
            steps -= n
            if self.failure is None and self.sim.step_count % per_tick == 0:
                self.publish_state()

    def _watch_recorder(self) -> None:
        """A recording that failed (a full disk) stops with one error line; the run goes on."""
        if self.recorder is not None and self.recording_error is None and self.recorder.error is not None:
            self.recording_error = self.recorder.error
            self.get_logger().error(f"recording stopped: {self.recording_error}; the simulation goes on")

    # --- output ------------------------------------------------------------------------------
    def _now_ns(self) -> int:
        """Now on the node's clock: simulated time when it publishes /clock, ROS time otherwise."""
        if self.publish_clock:
            return round(self.sim.t * 1e9)
        if not self.follow_clock:
            return time.time_ns()  # ROS time without use_sim_time is the system clock (cheaper to read)
        return self.get_clock().now().nanoseconds

    def _state_stamp_ns(self) -> int:
        """The header stamp of the state now: the node-clock time of this simulated instant
        (command stamps map back through the same origin, so a state and a command stamped
        alike mean one instant). Where simulated time runs at another pace than ROS time
        (real_time_factor other than 1, without publish_clock), the time it is published."""
        if self.publish_clock:
            return round(self.sim.t * 1e9)
        if self.follow_clock or self.rtf == 1.0:
            return self._sim_instant_ns()
        return self._now_ns()

    def publish_state(self) -> None:
        out = self.sim.outputs()
        if not all(math.isfinite(float(v)) for v in out.values()):
            return  # a NaN never reaches a topic
        stamp_ns = self._state_stamp_ns()
        if self.clock_pub is not None:
            self._publish([(self.clock_pub, cdr.clock(stamp_ns))], stamp_ns)
        log_ns = stamp_ns if self.publish_clock else self._now_ns()  # when it is published
        p = self.sim.params
        piston, rod = messages.chamber_pressures(out, stamp_ns)
        tick: list[tuple[Any, Any]] = [  # CDR bytes, packed without message objects
            (self.state_pub, messages.drive_state(out, stamp_ns)),
            (self.joint_pub, messages.joint_state(out, stamp_ns, p)),
            (self.p1_pub, piston),
            (self.p2_pub, rod),
            (self.force_pub, messages.rod_force(out, stamp_ns)),
        ]
        if self.drive.followed is not None:  # the controller drove in this tick: its setpoint now
            tick.append((self.setpoint_pub, setpoint_cdr(JOINTS[0], *self.drive.followed.at(self.sim.t), stamp_ns)))
        self._ticks += 1
        if self._ticks % self._markers_every == 0:
            tick.append((self.markers_pub, crane_markers(out, Time(nanoseconds=stamp_ns).to_msg(), p)))
        self._publish(tick, log_ns)

    def publish_description(self) -> None:
        """The URDF of the current parameters on robot_description (transient local)."""
        if self.description_pub is not None:
            self._publish([(self.description_pub, String(data=urdf(self.sim.params)))], self._now_ns())

    def on_second(self) -> None:
        """Once a second: diagnostics, and the command topics' publishers for the bag."""
        if self.recorder is not None:
            self._watch_command_topics()
        with self.lock:
            self._watch_publishers()
        self.publish_diagnostics()

    @_locked
    def publish_diagnostics(self) -> None:
        out = self.sim.outputs() if self.failure is None else {}
        array = DiagnosticArray()
        stamp_ns = self._now_ns()
        array.header.stamp = Time(nanoseconds=stamp_ns).to_msg()

        def status(name: str, level: bytes, message: str, **values: Any) -> DiagnosticStatus:
            return DiagnosticStatus(
                level=level,
                name=f"boom_sim: {name}",
                message=message,
                hardware_id="boom_hydraulics",
                values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
            )

        if self.failure:
            array.status.append(status("simulation", DiagnosticStatus.ERROR, f"stopped: {self.failure}"))
        else:
            # resting on an end stop is normal; cavitation and an open relief valve are not
            warnings = [name for name in ("cavitation", "relief_open") if out.get(name)]
            notes = ["at_end_stop"] if out.get("at_end_stop") else []
            array.status.append(
                status(
                    "drive",
                    DiagnosticStatus.WARN if warnings else DiagnosticStatus.OK,
                    ", ".join(warnings + notes) or "ok",
                    sim_time_s=f"{self.sim.t:.3f}",
                    paused=self.paused,
                    substeps_most=self.sim.most_substeps,
                    energy_residual_j=f"{self.sim.energy_residual():.4g}",
                )
            )
        pacer = self.pacer
        behind = pacer.lag_s > 2.0 / self.rate_hz
        array.status.append(
            status(
                "real-time",
                DiagnosticStatus.WARN if (behind or pacer.late_ticks) else DiagnosticStatus.OK,
                "cannot keep up" if (behind or pacer.late_ticks) else "ok",
                lag_s=f"{pacer.lag_s:.4f}",
                clock_error_s=f"{pacer.clock_error_s:.6f}",
                dropped_backlogs=pacer.late_ticks,
                real_time_factor=self.rtf,
            )
        )
        pacer.late_ticks = 0
        dropped = self.commands_stale + self.commands_lost + self.commands_refused
        array.status.append(
            status(
                "commands",
                DiagnosticStatus.WARN if dropped else DiagnosticStatus.OK,
                "some commands were not applied" if dropped else "ok",
                received=self.commands_received,
                stale=self.commands_stale,  # older than command_timeout_s when received
                lost=self.commands_lost,  # dropped by the middleware before the node took them
                refused=self.commands_refused,  # the queue of future commands was full
            )
        )
        # what a re-simulation of the bag must know: boom-resim refuses a run with resets or pauses
        array.status.append(
            status(
                "run",
                DiagnosticStatus.OK,
                "ok",
                resets=self.resets,
                pauses=self.pauses,
                step_calls=self.steps_paused,
                clock_origin_shift_s=f"{self.origin_shift_s:.6f}",
            )
        )
        if self.recorder is not None:
            self._watch_recorder()
            if self.recording_error is not None:
                array.status.append(status("recording", DiagnosticStatus.ERROR, f"stopped: {self.recording_error}"))
            else:
                array.status.append(status("recording", DiagnosticStatus.OK, "ok", folder=str(self.recorder.folder)))
        self._publish([(self.diag_pub, array)], stamp_ns)


def _fail(message: str) -> None:
    print(f"boom_sim: error: {message}", file=sys.stderr, flush=True)
    raise SystemExit(2)


def _shield_signals() -> None:
    """From the first SIGINT or SIGTERM on, a second one (a terminal's Ctrl-C and the one
    ros2 launch forwards arrive together) must not interrupt finishing the bag."""

    def note(_signum: int, _frame: Any) -> None:
        print("boom_sim: still finishing; it ends by itself", file=sys.stderr, flush=True)

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, note)


def _finish(node: BoomSimNode) -> bool:
    """Stop the loop, finish the bag and say where it is, then leave the ROS graph; False
    when the recording failed (the bag is left for boom-bag-recover)."""
    node.stopping.set()
    if node.loop.is_alive():
        node.loop.join(timeout=5.0)
    if node.record_pending:
        print("boom_sim: no bag: /clock never arrived (use_sim_time), so the run never started", flush=True)
    recorder, recorded = node.recorder, True
    if recorder is not None:
        folder = recorder.close()
        counts = ", ".join(f"{t} {n}" for t, n in recorder.counts.items() if n)
        if recorder.error is not None:  # (it says how to recover the bag)
            print(f"boom_sim: error: recording failed: {recorder.error}", file=sys.stderr, flush=True)
            recorded = False
        else:
            print(f"boom_sim: bag {folder} ({counts})", flush=True)
    node.motion.destroy()
    node.destroy_node()
    return recorded


def main(args: list[str] | None = None) -> None:
    argv = sys.argv if args is None else args
    if any(a in ("-h", "--help") for a in ros_parameters.user_args(argv)[1:]):
        print(ros_parameters.usage())
        return
    try:
        for path in ros_parameters.params_files(argv):
            ros_parameters.check_params_file(path)
    except ConfigError as exc:
        _fail(str(exc))
    # The loop thread must get the GIL soon after its deadline; CPython's default 5 ms
    # switch interval showed as a 16 ms p99 tick period at 100 Hz.
    sys.setswitchinterval(0.0005)
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rcl's argument parser: a malformed -p or --ros-args rule
        _fail(f"cannot read the ROS arguments: {str(exc).splitlines()[0]}")
    try:
        node = BoomSimNode()
    except (BoomHydraulicsError, ParameterException) as exc:  # a bad params file or -p value
        rclpy.try_shutdown()
        _fail(str(exc))
    except (KeyboardInterrupt, ExternalShutdownException):  # SIGINT/SIGTERM while it compiles or starts
        _shield_signals()
        rclpy.try_shutdown()
        print("boom_sim: stopped while starting; nothing was recorded", file=sys.stderr, flush=True)
        return
    except Exception:
        if rclpy.ok():
            raise
        _shield_signals()  # a signal shut the context down under the start-up: a clean stop too
        print("boom_sim: stopped while starting; nothing was recorded", file=sys.stderr, flush=True)
        return
    try:
        node.start()
    except BoomHydraulicsError as exc:  # the bag cannot be started (a full disk, a read-only folder)
        node.motion.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
        print(f"boom_sim: error: {exc}", file=sys.stderr, flush=True)
        raise SystemExit(1) from None
    try:
        node.motion.spin_in_background()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # SIGINT/SIGTERM shut the context down; the executor may then fail building its
        # wait set (RCLError) instead of raising ExternalShutdownException: that is a
        # clean shutdown too. Anything else is a real error.
        if rclpy.ok():
            raise
    finally:
        _shield_signals()
        recorded = _finish(node)
        rclpy.try_shutdown()
    if not recorded:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
