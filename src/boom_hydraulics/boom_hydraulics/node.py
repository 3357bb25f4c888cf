"""ROS 2 node ``boom_sim``: the model core in a loop, driven by valve commands.

    ros2 run boom_hydraulics boom_sim --ros-args --params-file config/default.yaml

Physics runs at ``time_step_s``, several steps per tick of ``publish_rate_hz``; simulated
time follows the steady clock by elapsed time (times ``real_time_factor``; 0 runs as fast
as possible), so a late tick catches up. The ticks run in a thread of their own that
sleeps to absolute deadlines: an rclpy timer would wake the executor, which rebuilds its
wait set in Python, 100 times a second (29 % of a core measured, against about 10 %
this way). The executor serves commands, services and parameters; a lock keeps the two
threads from touching the simulation at once. Commands are applied by their stamps (see :mod:`command_queue`),
which makes a run depend only on the commands and their times, not on wall-clock jitter.
Topics, services and parameters are listed in the README.
"""

from __future__ import annotations

import functools
import math
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import serialize_message
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool

from boom_hydraulics_msgs.msg import DriveState, ValveCommand
from boom_hydraulics_msgs.srv import Reset, Step

from .command_queue import CommandedDrive, valve_opening
from .errors import BoomHydraulicsError, ConfigError, SimulationError
from .geometry import lever_rad_per_m
from .messages import drive_state
from .parameters import NAMES, describe, from_mapping
from .recording import BagRecorder, Topic, new_bag_folder, run_description
from .simulation import Simulator

#: Parameters of the node itself (not of the model): name -> (default, description, low, high).
NODE_PARAMETERS: dict[str, tuple[Any, str, float | None, float | None]] = {
    "publish_rate_hz": (100.0, "State publish (tick) rate [Hz]", 1.0, 1000.0),
    "real_time_factor": (1.0, "Simulated seconds per wall second; 0: as fast as possible", 0.0, 1000.0),
    "publish_clock": (False, "Publish /clock and stamp messages with simulated time", None, None),
    "command_timeout_s": (
        0.5,
        "Valve returns to 0 when no command arrived for this long (simulated s); 0: never",
        0.0,
        3600.0,
    ),
    "max_catch_up_s": (
        0.2,
        "Largest backlog a tick works off before the node gives up real-time lock [s]",
        0.001,
        10.0,
    ),
    "jit": (False, "Step with the numba-compiled model (a few seconds to compile at start)", None, None),
    "record": (True, "Record every published topic and received command to a bag (start only)", None, None),
    "record_folder": ("bags", "Folder in which each run's bag folder is created (start only)", None, None),
    "record_chunk_kib": (1024.0, "MCAP chunk size [KiB]: what a SIGKILL can lose at most (start only)", 1.0, 65536.0),
    "start_paused": (
        False,
        "Start paused (resume with ~/pause data: false), e.g. to queue a scenario first",
        None,
        None,
    ),
}

_NODE_ATTRIBUTES = {
    "publish_rate_hz": "rate_hz",
    "real_time_factor": "rtf",
    "publish_clock": "publish_clock",
    "command_timeout_s": "timeout_s",
    "max_catch_up_s": "max_catch_up_s",
}


def _type_name(msg_type: Any) -> str:
    """'pkg/msg/Type' of a generated message class."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def check_node_parameter(name: str, value: Any) -> None:
    """Raise ConfigError unless ``value`` fits node parameter ``name``."""
    default, _, low, high = NODE_PARAMETERS[name]
    if isinstance(default, str):
        if not isinstance(value, str) or not value:
            raise ConfigError(f"parameter '{name}' must be a non-empty string, got {value!r}")
    elif isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"parameter '{name}' must be true or false, got {value!r}")
    elif isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise ConfigError(f"parameter '{name}' must be a number in [{low}, {high}], got {value!r}")


def _locked(method: Callable) -> Callable:
    """Run an executor callback while holding the node's lock (the loop thread steps too)."""

    @functools.wraps(method)
    def wrapper(self: BoomSimNode, *args: Any) -> Any:
        with self.lock:
            return method(self, *args)

    return wrapper


def _descriptor(description: str, low: float | None, high: float | None, kind: str, choices=None):
    # dynamic typing: a params file may write 50 for 50.0; Parameters validates types itself
    desc = ParameterDescriptor(description=description, dynamic_typing=True)
    if kind == "float" and low is not None and high is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high))]
    if kind == "int" and low is not None:
        desc.integer_range = [IntegerRange(from_value=int(low), to_value=2**31 - 1, step=1)]
    if choices:
        desc.additional_constraints = f"one of: {', '.join(choices)}"
    return desc


def _model_descriptor(name: str) -> ParameterDescriptor:
    meta = describe(name)
    unit = f" [{meta['unit']}]" if meta["unit"] else ""
    return _descriptor(f"{meta['description']}{unit}", meta["low"], meta["high"], meta["type"], meta["choices"])


class BoomSimNode(Node):
    """Thin ROS shell around :class:`Simulator`."""

    def __init__(self) -> None:
        super().__init__("boom_sim")
        for name in NAMES:
            self.declare_parameter(name, describe(name)["default"], _model_descriptor(name))
        for name, (default, description, low, high) in NODE_PARAMETERS.items():
            kind = {float: "float", bool: "bool", str: "str"}[type(default)]
            self.declare_parameter(name, default, _descriptor(description, low, high, kind))
            check_node_parameter(name, self.get_parameter(name).value)
        self._read_node_parameters()
        params = from_mapping({name: self.get_parameter(name).value for name in NAMES})
        self.sim = Simulator(params, jit=bool(self.get_parameter("jit").value))
        if self.sim.jit:
            self.sim.step(0.0, 0)  # compile before the clock starts
        self.drive = CommandedDrive(self.sim, self.timeout_s)
        self.lock = threading.RLock()
        self.stopping = threading.Event()
        self.paused = bool(self.get_parameter("start_paused").value)
        self.failure: str | None = None
        self.lag_s = 0.0
        self.clock_error_s = 0.0
        self.late_ticks = 0

        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.state_pub = self.create_publisher(DriveState, "drive_state", state_qos)
        self.joint_pub = self.create_publisher(JointState, "joint_states", state_qos)
        self.p1_pub = self.create_publisher(FluidPressure, "piston_pressure", state_qos)
        self.p2_pub = self.create_publisher(FluidPressure, "rod_pressure", state_qos)
        self.force_pub = self.create_publisher(WrenchStamped, "rod_force", state_qos)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", state_qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", state_qos)
        # best-effort subscriptions accept commands from reliable and best-effort publishers
        self.create_subscription(ValveCommand, "valve_command", self.on_command, qos_profile_sensor_data)
        self.create_subscription(Float64MultiArray, "commands", self.on_command_array, qos_profile_sensor_data)
        self.create_service(Reset, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.create_service(Step, "~/step", self.on_step)
        self.add_on_set_parameters_callback(self.on_set_parameters)

        self._restart_clock()
        self.recorder = self._start_recording() if self.get_parameter("record").value else None
        self.diag_timer = self.create_timer(1.0, self.publish_diagnostics)
        self.loop = threading.Thread(target=self.run_loop, name="boom_sim_loop", daemon=True)
        p = self.sim.params
        self.get_logger().info(
            f"{p.mode} mode, {p.method} dt={p.time_step_s} s, {self.rate_hz:g} Hz, "
            f"real-time factor {self.rtf:g}{' (as fast as possible)' if self.rtf == 0 else ''}, "
            f"{'compiled' if self.sim.compiled else 'interpreted'}"
        )

    def _start_recording(self) -> BagRecorder:
        """A bag of every topic this node publishes and every command it receives."""
        # /clock always: publish_clock may be switched on while running
        pubs = [self.state_pub, self.joint_pub, self.p1_pub, self.p2_pub, self.force_pub, self.diag_pub, self.clock_pub]
        topics = [Topic(p.topic_name, _type_name(p.msg_type)) for p in pubs]
        topics += [
            Topic(self.resolve_topic_name("valve_command"), _type_name(ValveCommand), reliable=False),
            Topic(self.resolve_topic_name("commands"), _type_name(Float64MultiArray), reliable=False),
        ]
        custom = run_description(self.sim.params, round(self.clock_origin_s * 1e9), self.rate_hz, self.timeout_s)
        recorder = BagRecorder(
            new_bag_folder(self.get_parameter("record_folder").value),
            topics,
            chunk_size=round(self.get_parameter("record_chunk_kib").value * 1024),
            custom_data=custom,
        )
        self.get_logger().info(f"recording to {recorder.folder}")
        return recorder

    def _record(self, topic: str, msg: Any, stamp: Any) -> None:
        if self.recorder is not None:
            self.recorder.write(topic, stamp.sec * 1_000_000_000 + stamp.nanosec, serialize_message(msg))

    def _publish(self, messages: list[tuple[Any, Any]], stamp: Any) -> None:
        """Publish (publisher, message) pairs, then record them all: a tick cut short by
        shutdown leaves no partial tick in the bag."""
        for publisher, msg in messages:
            publisher.publish(msg)
        for publisher, msg in messages:
            self._record(publisher.topic_name, msg, stamp)

    # --- parameters -----------------------------------------------------------------------
    def _read_node_parameters(self) -> None:
        self.rate_hz = float(self.get_parameter("publish_rate_hz").value)
        self.rtf = float(self.get_parameter("real_time_factor").value)
        self.publish_clock = bool(self.get_parameter("publish_clock").value)
        self.timeout_s = float(self.get_parameter("command_timeout_s").value)
        self.max_catch_up_s = float(self.get_parameter("max_catch_up_s").value)

    @_locked
    def on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Validate a change as a whole (cross-field checks too); refuse it with the reason."""
        model_changes = {p.name: p.value for p in changes if p.name in NAMES}
        node_changes = {p.name: p.value for p in changes if p.name in NODE_PARAMETERS}
        try:
            for name, value in node_changes.items():
                if name not in _NODE_ATTRIBUTES:
                    raise ConfigError(f"parameter '{name}' takes effect at start only; restart the node to change it")
                check_node_parameter(name, value)
            new_params = from_mapping(model_changes, base=self.sim.params) if model_changes else None
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if new_params is not None:
            self.sim.set_parameters(new_params)
        if node_changes:
            self.get_logger().info(f"node parameters changed: {node_changes}")
            for name, value in node_changes.items():  # rclpy stores them after this returns
                setattr(self, _NODE_ATTRIBUTES[name], type(NODE_PARAMETERS[name][0])(value))
            self.drive.timeout_s = self.timeout_s  # the drive applies it
            self._restart_clock()
        return SetParametersResult(successful=True)

    # --- commands -------------------------------------------------------------------------
    def _stamp_to_sim_time(self, stamp: Any) -> float | None:
        """Simulated time a command stamp means; None for a zero (unset) stamp."""
        if stamp.sec == 0 and stamp.nanosec == 0:
            return None
        return stamp.sec + stamp.nanosec * 1e-9 - self.clock_origin_s

    def _accept(self, opening: float, stamp: Any | None) -> None:
        u = valve_opening(opening, self.sim.params.mode)
        if u is None:
            self.get_logger().warning(f"ignored non-finite valve opening {opening}", throttle_duration_sec=1.0)
            return
        if u != opening:
            self.get_logger().warning(f"valve opening {opening} clamped to {u:g}", throttle_duration_sec=1.0)
        at = self._stamp_to_sim_time(stamp) if stamp is not None else None
        if not self.drive.push(self.sim.t if at is None else at, u):
            self.get_logger().warning("too many future-stamped commands waiting; refused", throttle_duration_sec=1.0)

    @_locked
    def on_command(self, msg: ValveCommand) -> None:
        stamp = msg.header.stamp
        self._record(
            self.resolve_topic_name("valve_command"), msg, stamp if stamp.sec or stamp.nanosec else self._stamp()
        )
        self._accept(msg.opening, stamp)

    @_locked
    def on_command_array(self, msg: Float64MultiArray) -> None:
        self._record(self.resolve_topic_name("commands"), msg, self._stamp())
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
            self.sim.reset(request.rod_position_m if request.use_rod_position else None)
        except SimulationError as exc:
            response.success, response.message = False, str(exc)
            return response
        self.drive.reset()
        self.failure = None
        self._restart_clock()
        response.success, response.message = True, f"reset to q1 = {self.sim.y[0]:.4f} m"
        self.publish_state()
        return response

    @_locked
    def on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if request.data == self.paused:
            response.success, response.message = True, "already paused" if self.paused else "already running"
            return response
        self.paused = request.data
        if not self.paused:
            self._restart_clock()
        response.success, response.message = True, "paused" if self.paused else "resumed"
        return response

    @_locked
    def on_step(self, request: Step.Request, response: Step.Response) -> Step.Response:
        if not self.paused:
            response.success, response.message = False, "step works while paused; call ~/pause with data: true"
        elif self.failure:
            response.success, response.message = False, f"simulation stopped: {self.failure}; call ~/reset"
        else:
            self.advance(max(1, request.steps))
            response.success, response.message = self.failure is None, self.failure or "ok"
            self.publish_state()
        response.sim_time_s = self.sim.t
        return response

    # --- time and stepping ---------------------------------------------------------------------
    def _restart_clock(self) -> None:
        """Tie simulated time to the steady clock from now on (start, reset, resume)."""
        self.wall_origin = time.monotonic()
        self.sim_origin_steps = self.sim.step_count
        # command stamps are sim time when the node owns the clock, else ROS time mapped to sim time
        now = self.get_clock().now().nanoseconds * 1e-9
        self.clock_origin_s = 0.0 if self.publish_clock else now - self.sim.t

    def advance(self, steps: int) -> None:
        """Take ``steps`` physics steps, applying queued commands at their times."""
        if self.failure is not None:
            return
        try:
            self.drive.advance(steps)
        except SimulationError as exc:
            self.failure = str(exc)
            self.get_logger().error(f"simulation stopped, waiting for ~/reset: {exc}")

    def run_loop(self) -> None:
        """Tick at ``publish_rate_hz`` of wall time (back to back at real_time_factor 0)."""
        deadline = time.monotonic()
        while not self.stopping.is_set():
            if self.rtf == 0:
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
        dt = self.sim.params.time_step_s
        per_tick = max(1, round(1.0 / (self.rate_hz * dt)))
        elapsed = 0.0
        if self.rtf == 0:
            steps = per_tick
        else:
            elapsed = (time.monotonic() - self.wall_origin) * self.rtf  # simulated s due by now
            steps = int(elapsed / dt + 1e-9) - (self.sim.step_count - self.sim_origin_steps)
            self.lag_s = max(0.0, steps * dt - per_tick * dt) / self.rtf  # backlog beyond one tick
            max_steps = max(per_tick, round(self.max_catch_up_s * self.rtf / dt))
            if steps > max_steps:  # cannot keep up: work off what we may, drop the rest
                self.late_ticks += 1
                self.get_logger().warning(
                    f"{steps * dt / self.rtf:.3f} s behind real time; dropping the backlog",
                    throttle_duration_sec=5.0,
                )
                dropped_s = (steps - max_steps) * dt / self.rtf
                self.wall_origin += dropped_s
                if not self.publish_clock:
                    self.clock_origin_s += dropped_s  # ROS-time stamps map to the later sim time
                steps = max_steps
        if steps <= 0:
            return
        self.advance(steps)
        if self.rtf > 0:  # how far simulated time trailed the steady clock at this tick, in wall s
            self.clock_error_s = (elapsed - (self.sim.step_count - self.sim_origin_steps) * dt) / self.rtf
        if self.failure is None:
            self.publish_state()

    # --- output ------------------------------------------------------------------------------
    def _stamp(self):
        if self.publish_clock:
            return Time(nanoseconds=round(self.sim.t * 1e9)).to_msg()
        return self.get_clock().now().to_msg()

    def publish_state(self) -> None:
        out = self.sim.outputs()
        if not all(math.isfinite(float(v)) for v in out.values()):
            return  # a NaN never reaches a topic
        stamp = self._stamp()
        if self.publish_clock:
            self._publish([(self.clock_pub, Clock(clock=stamp))], stamp)
        msg = drive_state(out, stamp)

        p = self.sim.params
        lever = lever_rad_per_m(out["q1"], p.a_m, p.b_m)  # d(alpha)/dq1: boom torque = F / k
        joints = JointState()
        joints.header.stamp = stamp
        joints.name = ["boom_joint", "cylinder_joint"]
        joints.position = [float(out["alpha"]), float(out["q1"])]
        joints.velocity = [float(out["alpha_rate"]), float(out["v"])]
        joints.effort = [float(out["f_hyd"] / lever), float(out["f_hyd"])]

        tick: list[tuple[Any, Any]] = [(self.state_pub, msg), (self.joint_pub, joints)]
        for pub, frame, value in ((self.p1_pub, "piston_chamber", out["p1"]), (self.p2_pub, "rod_chamber", out["p2"])):
            fluid = FluidPressure(fluid_pressure=float(value), variance=0.0)
            fluid.header.stamp, fluid.header.frame_id = stamp, frame
            tick.append((pub, fluid))
        wrench = WrenchStamped()
        wrench.header.stamp, wrench.header.frame_id = stamp, "cylinder_rod"  # x along the rod, extending
        wrench.wrench.force.x = float(out["f_hyd"])
        tick.append((self.force_pub, wrench))
        self._publish(tick, stamp)

    @_locked
    def publish_diagnostics(self) -> None:
        out = self.sim.outputs() if self.failure is None else {}
        array = DiagnosticArray()
        array.header.stamp = self._stamp()

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
            flags = [name for name in ("at_end_stop", "cavitation", "relief_open") if out.get(name)]
            array.status.append(
                status(
                    "drive",
                    DiagnosticStatus.WARN if flags else DiagnosticStatus.OK,
                    ", ".join(flags) if flags else "ok",
                    sim_time_s=f"{self.sim.t:.3f}",
                    paused=self.paused,
                )
            )
        behind = self.lag_s > 2.0 / self.rate_hz
        array.status.append(
            status(
                "real-time",
                DiagnosticStatus.WARN if (behind or self.late_ticks) else DiagnosticStatus.OK,
                "cannot keep up" if (behind or self.late_ticks) else "ok",
                lag_s=f"{self.lag_s:.4f}",
                clock_error_s=f"{self.clock_error_s:.6f}",
                dropped_backlogs=self.late_ticks,
                real_time_factor=self.rtf,
            )
        )
        self.late_ticks = 0
        self._publish([(self.diag_pub, array)], array.header.stamp)


def main(args: list[str] | None = None) -> None:
    # The loop thread must get the GIL soon after its deadline; CPython's default 5 ms
    # switch interval showed as a 16 ms p99 tick period at 100 Hz.
    sys.setswitchinterval(0.0005)
    rclpy.init(args=args)
    try:
        node = BoomSimNode()
    except (BoomHydraulicsError, ParameterException) as exc:  # a bad params file or -p value
        print(f"boom_sim: error: {exc}", flush=True)
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    node.loop.start()
    try:
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
        node.stopping.set()
        node.loop.join(timeout=5.0)
        if node.recorder is not None:
            folder = node.recorder.close()
            counts = ", ".join(f"{t} {n}" for t, n in node.recorder.counts.items() if n)
            print(f"boom_sim: bag {folder} ({counts})", flush=True)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
