"""``boom-demo``: start the node, drive it through a lift-hold-lower cycle, report what it does.

The scenario is published as ValveCommand messages on the node's ``valve_command``
topic, the same path a user's ``ros2 topic pub`` takes; the node runs as its own process
through its real entry point and records the run to a bag under ``bags/``, which this
command then analyses (boom-analyze: signals, metrics, plots).
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from boom_hydraulics_msgs.msg import DriveState, ValveCommand

from ..cli.analyze import main as analyze_main
from ..cli.common import RaisingParser, run_main, summary
from ..errors import ConfigError
from ..solve.commands import CYCLE


class ScenarioDriver(Node):
    """Publishes the scenario's openings at 50 Hz and keeps the latest DriveState."""

    def __init__(self, scenario: tuple[tuple[float, float], ...]) -> None:
        super().__init__("boom_demo")
        self.scenario = scenario
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.create_publisher(ValveCommand, "valve_command", qos)
        self.create_subscription(DriveState, "drive_state", self.on_state, qos)
        self.state: DriveState | None = None
        self.start: float | None = None

    def on_state(self, msg: DriveState) -> None:
        self.state = msg

    def opening_at(self, t: float) -> float:
        u = 0.0
        for start, value in self.scenario:
            if t >= start:
                u = value
        return u

    def send(self, t: float) -> float:
        msg = ValveCommand()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.opening = self.opening_at(t)
        self.pub.publish(msg)
        return msg.opening


def main(argv: list[str] | None = None) -> int:
    return run_main("boom-demo", lambda: demo(argv))


def demo(argv: list[str] | None) -> int:
    parser = RaisingParser(prog="boom-demo", description=summary(__doc__))
    parser.add_argument("--params-file", default=None, help="params YAML for the node")
    parser.add_argument("--duration", type=float, default=9.0, help="scenario length in s (default 9)")
    parser.add_argument("--bags", type=Path, default=Path("bags"), help="folder the node records into (default bags)")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ConfigError(f"--duration must be a positive number of seconds, got {args.duration:g}")
    before = set(args.bags.glob("*_boom_sim")) if args.bags.is_dir() else set()

    node_exe = shutil.which("boom_sim")
    if node_exe is None:
        print("boom-demo: error: the boom_sim executable is not on PATH (run through tools/with-env)", file=sys.stderr)
        return 2
    cmd = [node_exe, "--ros-args", "-p", f"record_folder:={args.bags}"]
    if args.params_file:
        cmd += ["--params-file", args.params_file]
    node_proc = subprocess.Popen(cmd, env=os.environ.copy())
    rclpy.init()
    driver = ScenarioDriver(CYCLE)
    try:
        deadline = time.monotonic() + 20.0
        while driver.state is None:  # wait for the node to come up
            rclpy.spin_once(driver, timeout_sec=0.1)
            if node_proc.poll() is not None or time.monotonic() > deadline:
                print("boom-demo: error: the node did not start", file=sys.stderr)
                return 1
        print(" t [s]  opening  q1 [m]  alpha [deg]  p1 [MPa]  p2 [MPa]  energy [kJ]")
        start = time.monotonic()
        next_print = 0.0
        while (t := time.monotonic() - start) < args.duration:
            u = driver.send(t)
            rclpy.spin_once(driver, timeout_sec=0.02)
            if t >= next_print and driver.state is not None:
                s = driver.state
                print(
                    f"{t:6.1f}  {u:+7.2f}  {s.rod_position_m:6.4f}  {s.boom_angle_rad * 57.29578:11.2f}  "
                    f"{s.piston_pressure_pa / 1e6:8.2f}  {s.rod_pressure_pa / 1e6:8.2f}  "
                    f"{s.supply_energy_j / 1e3:11.2f}"
                )
                next_print += 0.5
    except KeyboardInterrupt:
        pass
    finally:
        driver.destroy_node()
        rclpy.try_shutdown()
        node_proc.send_signal(signal.SIGINT)
        try:
            node_proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            node_proc.kill()
    new_bags = sorted(set(args.bags.glob("*_boom_sim")) - before)
    if not new_bags:
        print("boom-demo: error: the node recorded no bag", file=sys.stderr)
        return 1
    return analyze_main([str(new_bags[-1])])


if __name__ == "__main__":
    sys.exit(main())
