"""The test's side of the ROS graph, shared by the tests that run the node."""

from __future__ import annotations

import os
import time
from collections.abc import Callable

import rclpy
from conftest import GUARD_S, HANDSHAKE_OPENING
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_srvs.srv import SetBool

from boom_hydraulics_msgs.msg import DriveState, ValveCommand
from boom_hydraulics_msgs.srv import Reset, Step


class Client:
    """The test's side of the ROS graph: commands out, state in, services."""

    def __init__(self, node_name: str = "/boom_sim", namespace: str | None = None) -> None:
        self.node = rclpy.create_node(f"test_client_{os.getpid()}", namespace=namespace)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.node.create_publisher(ValveCommand, "valve_command", qos)
        self.states: list[DriveState] = []
        self.joints: list[JointState] = []
        self.pressures: list[FluidPressure] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(DriveState, "drive_state", self.states.append, qos)
        self.node.create_subscription(JointState, "joint_states", self.joints.append, qos)
        self.node.create_subscription(FluidPressure, "piston_pressure", self.pressures.append, qos)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, qos)
        self.reset = self.node.create_client(Reset, f"{node_name}/reset")
        self.pause = self.node.create_client(SetBool, f"{node_name}/pause")
        self.step = self.node.create_client(Step, f"{node_name}/step")
        self.set_params = self.node.create_client(SetParameters, f"{node_name}/set_parameters")
        self.get_params = self.node.create_client(GetParameters, f"{node_name}/get_parameters")

    def spin_until(self, predicate: Callable[[], bool], timeout: float = GUARD_S, opening: float | None = None) -> bool:
        """Spin until ``predicate()`` (an event), publishing ``opening`` at about 50 Hz if given;
        False if the guard ``timeout`` passes first."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            if opening is not None:
                self.command(opening)
            rclpy.spin_once(self.node, timeout_sec=0.02)
        return predicate()

    def acting_on(self, opening: float, valve_command: float | None = None) -> bool:
        """Publish ``opening`` until the node's state shows it acts on it (its valve_command is
        ``valve_command``, default ``opening``): an event, where a stretch of simulated time
        would be a guess at how late the command arrives on a loaded machine."""
        expected = opening if valve_command is None else valve_command
        return self.spin_until(lambda: bool(self.states) and self.last().valve_command == expected, opening=opening)

    def handshake(self, opening: float = HANDSHAKE_OPENING) -> None:
        """Return once the node has taken every command this client sent so far (DDS discovery
        done both ways), leaving its valve at about ``opening`` (default: too small to move
        the boom). Each try sends a new value (``opening`` times 1 + k/1000) and waits 0.2 s for a
        state that shows it; the node takes one publisher's commands in order, so a state with
        the newest value means none is left on the way to act later (a late one would override
        a goal, or be missing from the node's bag)."""
        sent = 0

        def acted_on() -> bool:
            nonlocal sent
            value = opening * (1.0 + sent / 1000.0)
            sent += 1
            self.command(value)
            return self.spin_until(lambda: bool(self.states) and self.last().valve_command == value, 0.2)

        assert self.spin_until(acted_on), f"the node never acted on this client's commands ({sent} sent)"

    def status_values(self, status_suffix: str) -> dict[str, str]:
        """The key-values of the newest diagnostics status whose name ends in ``status_suffix``
        ({} before any)."""
        for array in reversed(self.diagnostics):
            for status in array.status:
                if status.name.endswith(status_suffix):
                    return {kv.key: kv.value for kv in status.values}
        return {}

    def spin_for(self, seconds: float, opening: float | None = None) -> None:
        """Spin, publishing ``opening`` at 50 Hz if given."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if opening is not None:
                self.command(opening)
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def sim_s(self) -> float:
        """The newest state's stamp, s: its simulated instant on the node's clock."""
        stamp = self.states[-1].header.stamp
        return stamp.sec + stamp.nanosec * 1e-9

    def spin_sim(self, seconds: float, opening: float | None = None) -> None:
        """Spin until the node's states show ``seconds`` more of simulated time, publishing
        ``opening`` at about 50 Hz if given. A state's stamp is its simulated instant, so a
        loaded machine only makes this take longer, never changes what it covers."""
        assert self.spin_until(lambda: bool(self.states)), "no drive_state from the node"
        end = self.sim_s() + seconds - 1e-9
        deadline = time.monotonic() + GUARD_S + 20.0 * seconds
        while self.sim_s() < end:
            assert time.monotonic() < deadline, f"simulated time stood still at {self.sim_s():.3f} s"
            if opening is not None:
                self.command(opening)
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def command(self, opening: float, stamp_s: float | None = None) -> None:
        msg = ValveCommand(opening=opening)
        if stamp_s is not None:
            msg.header.stamp.sec = int(stamp_s)
            msg.header.stamp.nanosec = round((stamp_s - int(stamp_s)) * 1e9)
        self.pub.publish(msg)

    def call(self, client, request, timeout: float = GUARD_S):
        assert client.wait_for_service(timeout_sec=timeout), f"service {client.srv_name} not available"
        future = client.call_async(request)
        assert self.spin_until(future.done, timeout)
        return future.result()

    def set_parameter(self, name: str, value: float):
        param = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value))
        return self.call(self.set_params, SetParameters.Request(parameters=[param])).results[0]

    def last(self) -> DriveState:
        return self.states[-1]
