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
position controller; so do joint commands on joint_commands, as ros2_control's JointState
topic hardware interface sends them (see :mod:`joint_commands`). Simulated time never runs
backwards: a reset puts the drive back to rest and time goes on. What the node does to its
own time line (resets, pauses, steps, resumes, dropped backlogs) it publishes on ~/events and
records (bags.run_events), so that boom-resim reproduces every run. The node publishes its
URDF (with a ros2_control tag naming those topics) on robot_description and the crane as
markers. Topics, services, the action and parameters: docs/ros-api.md.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from boom_hydraulics_msgs.msg import DriveState, EnergyLedger, ValveCommand
from boom_hydraulics_msgs.msg import SetpointPath as SetpointPathMessage
from boom_hydraulics_msgs.srv import Reset, Step

from ..bags import cdr, messages
from ..bags.diagnostics import RunCounts, diagnostics
from ..bags.encoding import RecordedPath, setpoint_cdr, setpoint_path_cdr
from ..bags.energy import energy_ledger_cdr, finite, ledger_every, ledger_now
from ..bags.recording import run_description
from ..bags.run_events import RunEvent
from ..errors import BoomHydraulicsError, ConfigError, SimulationError
from ..model.parameters import NAMES, from_mapping
from ..model.robot_description import JOINTS, urdf
from ..model.setpoints import SetpointPath
from ..solve import accelerate, outcomes
from ..solve.command_queue import CommandedDrive
from ..solve.simulation import Simulator
from . import node_parameters as ros_parameters
from .clock import ClockMode, Follow, NodeClock
from .commands import CommandIntake
from .joint_commands import JointCommands
from .motion import Motion, Plant
from .publishers import PublisherWatch
from .recording import NodeRecording
from .service_checks import pause_unchanged, step_refusal, steps_asked

#: Markers go out at most this often (they are for eyes, not for control).
MARKERS_HZ = 20.0
#: Parameters every rclpy node declares itself (rclpy's time source and type description service).
_RCLPY_OWN = ("use_sim_time", "start_type_description_service")


def _locked(method: Callable) -> Callable:
    """Run an executor callback while holding the node's lock (the loop thread steps too)."""

    @functools.wraps(method)
    def wrapper(self: BoomSimNode, *args: Any) -> Any:
        with self.lock:
            return method(self, *args)

    return wrapper


class BoomSimNode(Node):
    """Thin ROS shell around :class:`Simulator`: the topics, services and parameters, wired
    to the clock (:mod:`.clock`), the command intake (:mod:`.commands`), the position goals
    (:mod:`.motion`), the bag (:mod:`.recording`) and the diagnostics (:mod:`.diagnostics`)."""

    def __init__(self) -> None:
        # each subscription's topic as given, for PublisherWatch (/clock's is made in rclpy's __init__)
        self.topics_as_given: dict[Subscription, str] = {}
        # the start values (params files and -p) arrive as parameters, read through the public API
        super().__init__("boom_sim", automatically_declare_parameters_from_overrides=True)
        self._declare_parameters()
        params = from_mapping(
            {name: ros_parameters.plain(self.get_parameter(name).value) for name in ros_parameters.MODEL_NAMES}
        )
        mode = ClockMode.of(
            bool(self.get_parameter("publish_clock").value), bool(self.get_parameter("use_sim_time").value)
        )
        self.sim = Simulator(params, jit=bool(self.get_parameter("jit").value))
        if self.sim.compiles_first():  # (before a minute without a word: the first log line comes after)
            self.get_logger().info(accelerate.compiling_notice(params.mode, params.method, "this start"))
        self.sim.warm()  # compile (or load from the cache) what it steps with, before the clock starts
        self.drive = CommandedDrive(self.sim, float(self.get_parameter("command_timeout_s").value))
        self.lock = threading.RLock()
        self.stopping = threading.Event()
        self.paused = bool(self.get_parameter("start_paused").value)
        self.failure: str | None = None
        #: why the bag could not be started on a shared clock's first tick (the process exits 1 with it)
        self.start_failure: str | None = None
        self._substeps_logged = self.sim.most_substeps  # the substeps the log has told about
        self.clock = NodeClock(
            mode,
            self.get_clock(),
            self.sim,
            float(self.get_parameter("publish_rate_hz").value),
            float(self.get_parameter("real_time_factor").value),
            float(self.get_parameter("max_catch_up_s").value),
        )

        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.state_pub = self.create_publisher(DriveState, "drive_state", state_qos)
        self.joint_pub = self.create_publisher(JointState, "joint_states", state_qos)
        self.p1_pub = self.create_publisher(FluidPressure, "piston_pressure", state_qos)
        self.p2_pub = self.create_publisher(FluidPressure, "rod_pressure", state_qos)
        self.force_pub = self.create_publisher(WrenchStamped, "rod_force", state_qos)
        self.hinge_pub = self.create_publisher(WrenchStamped, "hinge_wrench", state_qos)
        self.markers_pub = self.create_publisher(MarkerArray, "~/markers", state_qos)
        self.setpoint_pub = self.create_publisher(JointState, "~/setpoint", state_qos)
        # each path the controller starts to follow, exactly (boom-resim follows it again)
        self.setpoint_path_pub = self.create_publisher(SetpointPathMessage, "~/setpoint_path", state_qos)
        self.energy_pub = self.create_publisher(EnergyLedger, "~/energy", state_qos)
        # what the node did to its own time line (resets, pauses, steps, dropped backlogs): JSON lines
        self.events_pub = self.create_publisher(
            String, "~/events", QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        )
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.description_pub = (
            self.create_publisher(String, "robot_description", latched)
            if self.get_parameter("publish_robot_description").value
            else None
        )
        self._markers_every = max(1, round(self.clock.rate_hz / MARKERS_HZ))
        self._energy_every = ledger_every(self.clock.rate_hz)
        self._ticks = 0
        self._messages = messages.TickMessages(self.sim.params)
        # in the order TickMessages.state packs them
        self._state_pubs = (
            *(
                self.state_pub,
                self.joint_pub,
                self.p1_pub,
                self.p2_pub,
                self.force_pub,
                self.hinge_pub,
                self.markers_pub,
            ),
        )
        self._description_due = False  # a parameter change asks for robot_description again
        self._checked: Any = None  # the model parameters on_set checked, for post_set to apply
        self._undeclared_refusal: str | None = None  # before_set's refusal of a name not declared, for on_set
        self._changed_at_ns = 0
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", state_qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", state_qos) if mode is ClockMode.PUBLISHED else None

        command_topics = {
            self.resolve_topic_name("valve_command"): ValveCommand,
            self.resolve_topic_name("commands"): Float64MultiArray,
        }
        self.joint_commands_topic = self.resolve_topic_name("joint_commands")
        self.publisher_watch = PublisherWatch(self, self.topics_as_given)
        self.recording = NodeRecording(
            self,
            self.clock.now_ns,
            {**command_topics, self.joint_commands_topic: JointState},
            self.publisher_watch.reaching,
            record=bool(self.get_parameter("record").value),
            folder=self.get_parameter("record_folder").value,
            chunk_kib=self.get_parameter("record_chunk_kib").value,
            flush_s=float(self.get_parameter("record_flush_s").value),
            ordered=mode is ClockMode.FOLLOWED,  # (a shared clock stands still between its ticks)
        )
        self.commands = CommandIntake(
            command_topics, self.drive, self.clock, self.get_logger(), self.recording.received
        )
        # best-effort subscriptions accept commands from reliable and best-effort publishers;
        # raw: the bytes as received are recorded, and parsed once there
        self.create_subscription(ValveCommand, "valve_command", self.on_command, qos_profile_sensor_data, raw=True)
        self.create_subscription(
            Float64MultiArray, "commands", self.on_command_array, qos_profile_sensor_data, raw=True
        )
        self.run_counts = RunCounts()
        self.create_service(Reset, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.create_service(Step, "~/step", self.on_step)
        self.add_pre_set_parameters_callback(self.before_set_parameters)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.after_set_parameters)

        plant = Plant(
            self.lock,
            self.sim,
            self.drive,
            self.get_logger(),
            self.stopping,
            lambda: self.failure,
            self.clock.stamp_to_sim_time,
            self.announce_path,
        )
        self.motion = Motion(plant, self.get_name(), self.get_namespace())
        self.drive.on_override = self.motion.on_override
        self.joint_commands = JointCommands(plant, self.clock, self.motion.stop)
        self.create_subscription(JointState, "joint_commands", self.on_joint_command, qos_profile_sensor_data, raw=True)
        self.create_subscription(
            JointTrajectory,
            "~/joint_trajectory",
            self.motion.on_trajectory,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
        )

        if mode is ClockMode.FOLLOWED:
            # the node's last subscription: in each turn of the executor the command topics' messages
            # are taken before the /clock that came after them, and the loop steps no further (clock.followed_ns)
            self.create_subscription(
                Clock, "/clock", self.on_clock, QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
            )
        self.clock.restart()
        self.diag_timer = self.create_timer(1.0, self.on_second)
        self.loop = threading.Thread(target=self.run_loop, name="boom_sim_loop", daemon=True)
        p = self.sim.params
        if self._ignored_scenario:
            self.get_logger().info(
                "the command_* parameters describe boom-sim's headless scenario; this node takes "
                "its valve commands on valve_command and commands"
            )
        rtf = self.clock.rtf
        pace = (
            "following the ROS clock (use_sim_time)"
            if mode is ClockMode.FOLLOWED
            else f"real-time factor {rtf:g}{' (as fast as possible)' if rtf == 0 else ''}"
        )
        drive = f", drive {p.drive}" if p.mode == "physical" else ""
        self.get_logger().info(
            f"{p.mode} mode, {p.method} dt={p.time_step_s} s, {self.clock.rate_hz:g} Hz, {pace}, "
            f"{'compiled' if self.sim.compiled else 'interpreted'}{drive}"
        )

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        """rclpy's, without the default QoS event handlers: each is a waitable that the
        executor goes through in Python at every command received. With them, at commands
        of 100 Hz the node took 22.6-24.4 % of a core at real time; without, 18.9-19.2 %
        (bench/bench_node.py's real-time run). A subscriber asking for QoS these publishers
        do not offer is still told so where it subscribes (its own default handler); a publisher
        offering what this node's subscriptions cannot take is told of by
        :class:`.publishers.PublisherWatch`."""
        kwargs.setdefault("event_callbacks", PublisherEventCallbacks(use_default_callbacks=False))
        return super().create_publisher(*args, **kwargs)

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Any, qos_profile: Any, **kwargs: Any
    ) -> Subscription:
        """rclpy's, without the default QoS event handlers, for the same reason as
        :meth:`create_publisher`: each command received woke the executor into two wait sets
        holding the subscriptions' handlers, two each. A publisher whose messages cannot arrive
        (another type, QoS the subscription cannot take) is told of once a second instead
        (:class:`.publishers.PublisherWatch`, which looks its publishers up by ``topic``)."""
        kwargs.setdefault("event_callbacks", SubscriptionEventCallbacks(use_default_callbacks=False))
        subscription = super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)
        self.topics_as_given[subscription] = topic
        return subscription

    def destroy_subscription(self, subscription: Subscription) -> bool:
        """rclpy's; its topic as given is forgotten."""
        self.topics_as_given.pop(subscription, None)
        return super().destroy_subscription(subscription)

    def start(self) -> None:
        """Start stepping: simulated time 0 is now (on the node's own clock; on a shared one,
        the first /clock), so that a command stamped in ROS time acts at its stamp."""
        with self.lock:
            if not self.clock.follows:
                self.clock.restart()
                self._begin_recording()
            self.publish_description()
        self.loop.start()

    def _begin_recording(self) -> None:
        """Open the bag, if asked for, at the time origin: every topic this node publishes."""
        pubs = [self.state_pub, self.joint_pub, self.p1_pub, self.p2_pub, self.force_pub, self.hinge_pub, self.diag_pub]
        pubs += [self.markers_pub, self.setpoint_pub, self.setpoint_path_pub, self.energy_pub, self.events_pub]
        pubs += [pub for pub in (self.description_pub, self.clock_pub) if pub is not None]
        if self.recording.pending:
            description = run_description(
                self.sim.params,
                self.clock.origin_ns,
                self.clock.rate_hz,
                self.drive.timeout_s,
                node=self.get_fully_qualified_name(),
                events_topic=self.events_pub.topic_name,
                clock=self.clock.mode.value,
                real_time_factor=self.clock.rtf,
            )
            self.recording.begin(pubs, description)

    def destroy(self) -> None:
        """Leave the ROS graph: the action's helper node, then this node."""
        self.motion.destroy()
        self.destroy_node()

    # --- parameters -----------------------------------------------------------------------
    def _declare_parameters(self) -> None:
        """Declare every parameter, typed (an integer for a float is taken as that float),
        from the start values rclpy declared, after refusing keys for this node that name no
        parameter, values of another type, and values out of range."""
        given = {name: self.get_parameter(name) for name in self.list_parameters([], 0).names}
        ros_parameters.check_known(given)
        for name in _RCLPY_OWN:  # (rclpy declared them with the start value; refuse what it only logs)
            if given[name].type_ is not Parameter.Type.BOOL:
                raise InvalidParameterTypeException(given[name], Parameter.Type.BOOL.name)
        for name in given:
            if name not in _RCLPY_OWN:
                self.undeclare_parameter(name)  # declared again below, with its descriptor
        given = {name: ros_parameters.typed(p) for name, p in given.items()}
        # the scenario (command_*) is boom-sim's: not declared, and said once to be ignored
        self._ignored_scenario = ros_parameters.ignored_scenario({n: p.value for n, p in given.items()})
        # our checks first: they name the unit and the fix, where rclpy's range check does not
        ros_parameters.check_node_model(
            from_mapping({name: ros_parameters.plain(p.value) for name, p in given.items() if name in NAMES})
        )
        for name, p in given.items():
            if name in ros_parameters.NODE_PARAMETERS:
                ros_parameters.check_node_parameter(name, p.value)
        for name in ros_parameters.all_names():
            descriptor = ros_parameters.descriptor(name)
            value = ros_parameters.default(name)
            if name in given:  # as rclpy checks a start value against the declared type
                value = given[name].value
                if given[name].type_.value != descriptor.type:
                    raise InvalidParameterTypeException(given[name], Parameter.Type(descriptor.type).name)
            self.declare_parameter(name, value, descriptor, ignore_override=True)

    def before_set_parameters(self, changes: list[Parameter]) -> list[Parameter]:
        """An integer for a float parameter becomes that float, before rclpy checks the type. A
        name the node does not declare is refused by on_set with a reason that names it and the
        closest parameter: it stands in as publish_rate_hz at its present value, so that rclpy's
        own refusal ('Invalid access to undeclared parameter(s): []') does not come first."""
        reasons = [reason for p in changes if (reason := ros_parameters.undeclared(p.name)) is not None]
        self._undeclared_refusal = reasons[0] if reasons else None
        if reasons:
            stand_in = self.get_parameter("publish_rate_hz")
            return [Parameter(stand_in.name, stand_in.type_, stand_in.value)]
        return [ros_parameters.typed(p) for p in changes]

    def on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Validate a change as a whole (cross-field checks too); refuse it with the reason.
        A new method or mode is compiled (or loaded) here, while the loop goes on stepping,
        so that applying it (:meth:`after_set_parameters`) holds the loop up for no longer than a tick."""
        self._checked = None
        if self._undeclared_refusal is not None:
            reason, self._undeclared_refusal = self._undeclared_refusal, None
            return SetParametersResult(successful=False, reason=reason)
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
            warming = Simulator(new_params, jit=True)
            if warming.compiles_first():
                self.get_logger().info(accelerate.compiling_notice(new_params.mode, new_params.method, "this change"))
            warming.warm()
        self._checked = new_params
        return SetParametersResult(successful=True)

    def _check_changes(self, changes: list[Parameter]) -> tuple[SetParametersResult | None, Any]:
        """(a refusal or None, the model parameters after the change or None)."""
        model_changes = {p.name: ros_parameters.plain(p.value) for p in changes if p.name in NAMES}
        node_changes = {p.name: p.value for p in changes if p.name in ros_parameters.NODE_PARAMETERS}
        for p in changes:
            if p.name == "use_sim_time" and bool(p.value) != self.clock.follows:
                reason = (
                    "use_sim_time is start-only: the clock a run follows is chosen when it starts; "
                    "restart the node with -p use_sim_time:=" + ("true" if p.value else "false")
                )
                return SetParametersResult(successful=False, reason=reason), None
        try:
            for name, value in node_changes.items():
                ros_parameters.check_node_parameter(name, value)
            new_params = from_mapping(model_changes, base=self.sim.params) if model_changes else None
            if new_params is not None:
                ros_parameters.check_node_model(new_params)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc)), None
        return None, new_params

    def after_set_parameters(self, changes: list[Parameter]) -> None:
        """Apply the change on_set checked; record it as rclpy announces it on /parameter_events,
        stamped with the node-clock time of the simulated instant it took effect at (boom-resim
        applies it there); publish the robot description again when a dimension changed."""
        new_params, self._checked = self._checked, None
        with self.lock:
            self._apply_changes(changes, new_params)
        if self._description_due:
            self._description_due = False
            self.publish_description()
        changed = [(p.name, p.type_.value, ros_parameters.plain(p.value)) for p in changes]
        self.recording.parameter_event(self._changed_at_ns, changed)

    def _apply_changes(self, changes: list[Parameter], new_params: Any) -> None:
        """Apply a checked change (the caller holds the lock)."""
        node_changes = {p.name: p.value for p in changes if p.name in ros_parameters.NODE_PARAMETERS}
        dt_before, steps_before = self.sim.params.time_step_s, self.sim.step_count
        if new_params is not None:
            if new_params.mode != "physical":
                self.motion.stop("mode changed to paper, which has no position control")
            self.sim.set_parameters(new_params)
            self.drive.parameters_changed()
            self._description_due = True
        if node_changes:
            self.get_logger().info(f"node parameters changed: {node_changes}")
            clock = self.clock
            value = {
                "publish_rate_hz": clock.rate_hz,
                "real_time_factor": clock.rtf,
                "command_timeout_s": self.drive.timeout_s,
                "max_catch_up_s": clock.pacer.max_catch_up_s,
            }
            value.update({name: float(v) for name, v in node_changes.items()})
            self.drive.timeout_s = value["command_timeout_s"]  # the drive applies it
            clock.set_pace(value["publish_rate_hz"], value["real_time_factor"], value["max_catch_up_s"])
            self._markers_every = max(1, round(clock.rate_hz / MARKERS_HZ))
            self._energy_every = ledger_every(clock.rate_hz)
        if "real_time_factor" in node_changes:
            origin_before = self.clock.origin_ns
            self.clock.restart()  # a new pace: simulated time follows the clock afresh from here
            self._record_event("pace", origin_before, real_time_factor=self.clock.rtf)
        elif new_params is not None or node_changes:
            # the time origin stays: the change takes no simulated time (a new mode resets the state)
            self.clock.rebase(dt_before, steps_before)
        # the node-clock time of the simulated instant the change takes effect at
        self._changed_at_ns = self.clock.sim_instant_ns()

    # --- commands -------------------------------------------------------------------------
    @_locked
    def on_clock(self, msg: Clock) -> None:
        """/clock, taken after the commands that came before it (use_sim_time): how far the loop may step."""
        self.clock.take(msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)

    @_locked
    def on_command(self, data: bytes, info: dict) -> None:
        self.commands.on_valve_command(data, info)

    @_locked
    def on_command_array(self, data: bytes, info: dict) -> None:
        self.commands.on_command_array(data, info)

    @_locked
    def on_joint_command(self, data: bytes, info: dict) -> None:
        """A JointState on joint_commands: recorded as received, then taken (:mod:`.joint_commands`)."""
        self.recording.received(self.joint_commands_topic, data, info)
        self.joint_commands.on_message(deserialize_message(data, JointState))

    # --- services -------------------------------------------------------------------------
    @_locked
    def on_reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        origin_before, stopped = self.clock.origin_ns, self.failure is not None
        rod_position_m = request.rod_position_m if request.use_rod_position else None
        try:
            self._back_to_rest("reset (~/reset)", rod_position_m)
        except SimulationError as exc:
            response.success, response.message = False, str(exc)
            return response
        self._record_reset("~/reset", origin_before, rod_position_m, stopped)
        response.success, response.message = True, f"reset to q1 = {self.sim.y[0]:.4f} m"
        self.run_counts.resets += 1
        self.publish_state()
        self.publish_diagnostics()  # the bag keeps the count at once: boom-resim reads it
        return response

    @_locked
    def on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        unchanged = pause_unchanged(request.data, self.paused)
        if unchanged is not None:
            response.success, response.message = True, unchanged
            return response
        self.paused = request.data
        origin_before = self.clock.origin_ns
        if self.paused:
            self.run_counts.pauses += 1
        else:
            self.clock.restart()
        self._record_event("pause" if self.paused else "resume", origin_before)
        response.success, response.message = True, "paused" if self.paused else "resumed"
        self.publish_diagnostics()  # the bag keeps the count at once: boom-resim reads it
        return response

    @_locked
    def on_step(self, request: Step.Request, response: Step.Response) -> Step.Response:
        steps = steps_asked(request.steps)
        refusal = step_refusal(self.paused, self.failure, steps, self.sim.params.time_step_s)
        if refusal is not None:
            response.success, response.message = False, refusal
        else:
            self._record_event("step", self.clock.origin_ns, steps=steps)
            self.advance(steps)
            self.run_counts.step_calls += 1
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
        dt_before, steps_before = self.sim.params.time_step_s, self.sim.step_count
        self.sim.reset(rod_position_m, keep_time=True)
        self.motion.stop(why)
        self.drive.reset()
        self.failure = None
        if stopped:  # a stopped simulation stood still, as a paused one does: it goes on from now
            self.clock.restart()
        else:  # time runs on from here, tied to the clock as before (the reset counts steps from 0)
            self.clock.rebase(dt_before, steps_before)

    def _record_event(self, kind: str, origin_before_ns: int, **details: Any) -> None:
        """Publish and record what the node did to its own time line (:mod:`..bags.run_events`),
        now: at this simulated time, after the states published so far, with the time origin
        as it is now and how far the event moved it from ``origin_before_ns``."""
        clock = self.clock
        moved = clock.origin_ns - origin_before_ns
        event = RunEvent(kind, self.sim.t, self._ticks, clock.origin_ns, moved, **details)
        self.recording.publish([(self.events_pub, String(data=event.to_json()))], clock.now_ns())

    def _record_reset(self, cause: str, origin_before_ns: int, rod_position_m: float | None, stopped: bool) -> None:
        """A reset's event: its cause, where it put the rod, whether the simulation had stopped, the state after it."""
        state = [float(x) for x in self.sim.y]
        self._record_event(
            "reset", origin_before_ns, cause=cause, rod_position_m=rod_position_m, stopped=stopped, state=state
        )

    def _follow_ros_clock(self) -> bool:
        """use_sim_time: whether the loop may step now. No /clock yet: wait. The first /clock
        starts the bag. A jump back (a world reset): the drive goes back to rest, as ~/reset
        does, and follows the clock from there."""
        seen_s = self.clock.seen_s
        follow = self.clock.follow()
        if follow is Follow.WAIT:
            return False
        if follow is Follow.FIRST and self.recording.pending:
            try:
                self._begin_recording()
            except BoomHydraulicsError as exc:  # as on the node's own clock, where it starts the bag
                # at start: the node ends with one line and status 1 (it stepped on, stopped for good)
                self.start_failure = str(exc)
                self.stopping.set()
                rclpy.try_shutdown(context=self.context)  # the main thread's spin ends; it says why
                return False
            self.publish_description()  # (transient local: published again, so the bag has it)
        elif follow is Follow.JUMPED_BACK:
            self.get_logger().warning(
                f"the ROS clock jumped back from {seen_s:.3f} s to {self.clock.read_s:.3f} s: "
                "the drive is reset to rest, as ~/reset does (simulated time runs on)"
            )
            origin_before = self.clock.origin_ns
            self._back_to_rest("the ROS clock jumped back")
            self.run_counts.resets += 1  # a reset as ~/reset's: boom-resim must know of it
            self.clock.restart()
            self._record_reset("the ROS clock jumped back", origin_before, None, False)
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
                f"{outcomes.substeps_cause(p.method)}: {p.method} takes {self._substeps_logged} substeps per time "
                f"step of {p.time_step_s:g} s here (the step and the outputs stay at {p.time_step_s:g} s)"
            )

    def run_loop(self) -> None:
        """Tick at ``publish_rate_hz`` of wall time (back to back at real_time_factor 0)."""
        deadline = time.monotonic()
        while not self.stopping.is_set():
            deadline = self.clock.wait_for_tick(deadline, self.stopping)
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
        clock = self.clock
        if clock.follows and not self._follow_ros_clock():
            return
        dt = self.sim.params.time_step_s
        origin_before = clock.origin_ns
        tick = clock.due()
        if tick.dropped_s:  # cannot keep up: the pacer gave up the backlog beyond max_catch_up_s
            self._record_event("backlog_dropped", origin_before, dropped_s=tick.dropped_s)
            behind_s = tick.steps * dt / clock.pacer.real_time_factor + tick.dropped_s
            self.get_logger().warning(
                f"{behind_s:.3f} s behind {'the ROS clock' if clock.follows else 'real time'}; dropping the backlog",
                throttle_duration_sec=5.0,
            )
        if tick.steps <= 0:
            return
        if clock.follows:
            # up to the last publishing instant due: between ticks the drive is at a state it
            # published, where it takes commands (so the bag tells where it took each)
            per_tick, taken = clock.pacer.per_tick(dt), self.sim.step_count
            self._advance_publishing((taken + tick.steps) // per_tick * per_tick - taken, per_tick)
        else:
            self.advance(tick.steps)
            if self.failure is None:
                self.publish_state()
        clock.pacer.settled(self.sim.step_count, dt)
        self.recording.watch()

    def _advance_publishing(self, steps: int, per_tick: int) -> None:
        """Take ``steps`` steps, publishing at every multiple of ``per_tick`` steps: on a shared
        clock the states come at publish_rate_hz of the clock's time, whatever its pace."""
        while steps > 0 and self.failure is None:
            n = min(steps, per_tick - self.sim.step_count % per_tick)
            self.advance(n)
            steps -= n
            if self.failure is None and self.sim.step_count % per_tick == 0:
                self.publish_state()

    # --- output ------------------------------------------------------------------------------
    def publish_state(self) -> None:
        """The state messages of now (and the markers, every ``_markers_every`` call), as CDR
        bytes packed with layouts bound once per parameter set (:class:`messages.TickMessages`)."""
        values = self.sim.published()  # (one compiled call)
        if not messages.finite(values):  # (the battery's outputs are NaN in paper mode: not among them)
            return  # a NaN never reaches a topic
        clock = self.clock
        stamp_ns = clock.state_stamp_ns()
        if self.clock_pub is not None:
            self.recording.publish([(self.clock_pub, cdr.clock(stamp_ns))], stamp_ns)
        log_ns = stamp_ns if clock.publishes else clock.now_ns()  # when it is published
        if self._messages.params is not self.sim.params:  # new parameters: new dimensions for the markers
            self._messages = messages.TickMessages(self.sim.params)
        self._ticks += 1
        packed = self._messages.state(values, stamp_ns, markers=self._ticks % self._markers_every == 0)
        tick = list(zip(self._state_pubs, packed))  # (the markers' publisher is the last: only when packed)
        if self.drive.followed is not None:  # the controller drove in this tick: its setpoint now
            tick.append((self.setpoint_pub, setpoint_cdr(JOINTS[0], *self.drive.followed.at(self.sim.t), stamp_ns)))
        if self._ticks % self._energy_every == 0:  # the energy ledger, at ENERGY_HZ (none in paper mode)
            sim = self.sim
            now = ledger_now(sim.params, sim.t, sim.y, sim.constants, sim.u)
            if now is not None and finite(now):
                tick.append((self.energy_pub, energy_ledger_cdr(now, stamp_ns)))
        self.recording.publish(tick, log_ns)

    def announce_path(self, path: SetpointPath, start: int) -> None:
        """The path the controller starts to follow now (caller holds the lock), on
        ~/setpoint_path and in the bag: stamped as the state of this instant, its knots' times
        from it in whole ns (the node follows them so: Plant.follow), logged now, as a run
        event, so that the bag tells between which of its states the node took it."""
        clock = self.clock
        recorded = RecordedPath.taken(path, self.sim.t, clock.state_stamp_ns(), start)
        message = [(self.setpoint_path_pub, setpoint_path_cdr(JOINTS[0], recorded))]
        self.recording.publish(message, clock.now_ns(), keep_early=True)  # (a goal before the first /clock too)

    def publish_description(self) -> None:
        """The URDF of the current parameters on robot_description (transient local), its
        ros2_control tag naming this node's joint command and state topics as resolved."""
        if self.description_pub is not None:
            description = urdf(self.sim.params, self.joint_commands_topic, self.joint_pub.topic_name)
            self.recording.publish([(self.description_pub, String(data=description))], self.clock.now_ns())

    def on_second(self) -> None:
        """Once a second: diagnostics, the command topics' publishers for the bag, and a
        warning for a publisher that cannot reach this node's subscriptions."""
        reaching = self.publisher_watch.look()  # (the one look at the graph: by the names as given)
        with self.lock:  # (the loop thread opens the bag, declaring command topics, under it)
            self.recording.watch_command_topics(reaching)
            self.commands.watch_publishers(reaching)
        self.publish_diagnostics()

    @_locked
    def publish_diagnostics(self) -> None:
        clock = self.clock
        stamp_ns = clock.now_ns()
        array = diagnostics(
            stamp_ns,
            self.sim,
            self.failure,
            self.paused,
            clock.pacer,
            clock.rate_hz,
            clock.rtf,
            self.commands.counts,
            self.run_counts,
            clock.origin_shift_s,
            self.recording.status() if self.recording.recorder is not None else None,
        )
        self.recording.publish([(self.diag_pub, array)], stamp_ns)
