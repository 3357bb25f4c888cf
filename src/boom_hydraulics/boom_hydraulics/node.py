"""ROS 2 node ``boom_sim``: the model core in a timer loop, driven by valve commands.

    ros2 run boom_hydraulics boom_sim --ros-args --params-file config/default.yaml

Subscribes ``valve_command`` (boom_hydraulics_msgs/ValveCommand); publishes
``drive_state`` (boom_hydraulics_msgs/DriveState) and ``joint_states``
(sensor_msgs/JointState) at ``publish_rate_hz``. Physics runs at ``time_step_s`` as
several steps per timer tick; simulated time follows the steady clock by elapsed time
(a late tick catches up), so the trajectory depends only on when commands arrive.
"""

from __future__ import annotations

import math
import time

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState

from boom_hydraulics_msgs.msg import DriveState, ValveCommand

from .errors import BoomHydraulicsError, SimulationError
from .geometry import lever_rad_per_m
from .parameters import NAMES, describe, from_mapping
from .simulation import Simulator

#: Extra steps a tick may take to catch up before the node gives up real-time lock.
_MAX_CATCH_UP_S = 0.5


def _descriptor(name: str) -> ParameterDescriptor:
    meta = describe(name)
    unit = f" [{meta['unit']}]" if meta["unit"] else ""
    # dynamic typing: a params file may write 50 for 50.0; Parameters validates the type itself
    desc = ParameterDescriptor(description=f"{meta['description']}{unit}", dynamic_typing=True)
    low, high = meta["low"], meta["high"]
    if meta["type"] == "float" and low is not None and high is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high))]
    if meta["type"] == "int" and low is not None:
        desc.integer_range = [IntegerRange(from_value=int(low), to_value=2**31 - 1, step=1)]
    if meta["choices"]:
        desc.additional_constraints = f"one of: {', '.join(meta['choices'])}"
    return desc


class BoomSimNode(Node):
    """Thin ROS shell around :class:`Simulator`."""

    def __init__(self) -> None:
        super().__init__("boom_sim")
        for name in NAMES:
            self.declare_parameter(name, describe(name)["default"], _descriptor(name))
        self.declare_parameter("publish_rate_hz", 100.0, ParameterDescriptor(description="State publish rate [Hz]"))
        self.declare_parameter(
            "command_timeout_s",
            0.5,
            ParameterDescriptor(description="Valve returns to 0 when no command arrived for this long [s]; 0: never"),
        )
        params = from_mapping({name: self.get_parameter(name).value for name in NAMES})
        self.sim = Simulator(params)
        self.command = 0.0
        self.last_command_time: float | None = None
        self.failed = False
        self.rate_hz = float(self.get_parameter("publish_rate_hz").value)
        self.timeout_s = float(self.get_parameter("command_timeout_s").value)

        state_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.state_pub = self.create_publisher(DriveState, "drive_state", state_qos)
        self.joint_pub = self.create_publisher(JointState, "joint_states", state_qos)
        # best-effort subscription: accepts commands from reliable and best-effort publishers
        self.create_subscription(ValveCommand, "valve_command", self.on_command, qos_profile_sensor_data)

        self.start_wall = time.monotonic()
        self.timer = self.create_timer(1.0 / self.rate_hz, self.on_tick)
        self.get_logger().info(
            f"boom_sim: {params.mode} mode, {params.method} dt={params.time_step_s} s, publishing at {self.rate_hz} Hz"
        )

    def on_command(self, msg: ValveCommand) -> None:
        u = msg.opening
        if not math.isfinite(u):
            self.get_logger().warning(f"ignored non-finite valve opening {u}", throttle_duration_sec=1.0)
            return
        low = 0.0 if self.sim.params.mode == "paper" else -1.0
        if not low <= u <= 1.0:
            self.get_logger().warning(f"valve opening {u} clamped to [{low:g}, 1]", throttle_duration_sec=1.0)
            u = min(1.0, max(low, u))
        self.command = u
        self.last_command_time = time.monotonic()

    def on_tick(self) -> None:
        if self.failed:
            return
        now = time.monotonic()
        if self.timeout_s > 0 and self.last_command_time is not None and now - self.last_command_time > self.timeout_s:
            self.command = 0.0
        dt = self.sim.params.time_step_s
        target = (now - self.start_wall) / dt
        behind = int(target) - self.sim.step_count
        if behind * dt > _MAX_CATCH_UP_S:  # cannot keep up: drop the backlog, keep running
            self.get_logger().warning(
                f"{behind * dt:.3f} s behind real time; skipping ahead", throttle_duration_sec=5.0
            )
            self.start_wall += behind * dt - _MAX_CATCH_UP_S
            behind = int(_MAX_CATCH_UP_S / dt)
        if behind <= 0:
            return
        try:
            self.sim.step(self.command, behind)
        except SimulationError as exc:
            self.failed = True
            self.get_logger().error(f"simulation stopped: {exc}")
            return
        self.publish_state()

    def publish_state(self) -> None:
        out = self.sim.outputs()
        stamp = self.get_clock().now().to_msg()
        msg = DriveState()
        msg.header.stamp = stamp
        msg.header.frame_id = "boom_base"
        msg.rod_position_m = float(out["q1"])
        msg.rod_velocity_m_s = float(out["v"])
        msg.rod_acceleration_m_s2 = float(out["a"])
        msg.boom_angle_rad = float(out["alpha"])
        msg.boom_rate_rad_s = float(out["alpha_rate"])
        msg.piston_pressure_pa = float(out["p1"])
        msg.rod_pressure_pa = float(out["p2"])
        msg.piston_flow_m3_s = float(out["q_in1"])
        msg.rod_flow_m3_s = float(out["q_in2"])
        msg.hydraulic_force_n = float(out["f_hyd"])
        msg.load_force_n = float(out["f_load"])
        msg.valve_command = float(out["u"])
        msg.valve_opening = float(out["x_v"])
        msg.supply_power_w = float(out["power"])
        msg.supply_energy_j = float(out["supply_energy"])
        msg.valve_loss_energy_j = float(out["valve_loss_energy"])
        msg.at_end_stop = bool(out["at_end_stop"])
        msg.cavitation = bool(out["cavitation"])
        msg.relief_open = bool(out["relief_open"])
        self.state_pub.publish(msg)

        joints = JointState()
        joints.header.stamp = stamp
        joints.name = ["boom_joint", "cylinder_joint"]
        joints.position = [float(out["alpha"]), float(out["q1"])]
        joints.velocity = [float(out["alpha_rate"]), float(out["v"])]
        p = self.sim.params
        lever = lever_rad_per_m(out["q1"], p.a_m, p.b_m)  # d(alpha)/dq1: boom torque = F / k
        joints.effort = [float(out["f_hyd"] / lever), float(out["f_hyd"])]
        self.joint_pub.publish(joints)


def main(args: list[str] | None = None) -> None:
    rclpy.init(args=args)
    try:
        node = BoomSimNode()
    except BoomHydraulicsError as exc:
        print(f"boom_sim: error: {exc}")
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
