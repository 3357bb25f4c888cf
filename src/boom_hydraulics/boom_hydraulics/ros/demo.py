"""``boom-demo``: start the node, drive it through a lift-hold-lower cycle, report what it does.

The scenario is published as ValveCommand messages on the node's ``valve_command``
topic, the same path a user's ``ros2 topic pub`` takes; the node runs as its own process
through its real entry point and records the run to a bag under ``bags/``, which this
command then analyses (boom-analyze: signals, metrics, plots).

Stopping: Ctrl-C or SIGTERM ends the scenario; each is passed on to the node as one SIGINT
(the node runs in its own process group, so a terminal's Ctrl-C reaches it once, through
here), and boom-demo waits for the node to finish its bag, then exits 130 naming the bag.
If boom-demo is killed, the node gets SIGINT from the kernel (Linux: PR_SET_PDEATHSIG) and
still finishes its bag. boom-demo waits for the node to start for as long as it runs: a
start that finds no compiled model in the cache (``make setup`` fills it) compiles it, which
takes long on a busy machine.
"""

from __future__ import annotations

import ctypes
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import FrameType

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from boom_hydraulics_msgs.msg import DriveState, ValveCommand

from ..analysis.recordings import analyze, default_results_folder, report
from ..errors import ConfigError
from ..programs import RaisingParser, run_main, summary
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


PR_SET_PDEATHSIG = 1  # linux/prctl.h
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` that has the kernel send the child SIGINT when boom-demo dies (even by
    SIGKILL), so that the node finishes its bag instead of recording on as an orphan. Linux only."""
    if not sys.platform.startswith("linux"):
        return None
    libc = ctypes.CDLL(None, use_errno=True)  # loaded before the fork: the child only calls it
    parent = os.getpid()

    def preexec() -> None:
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGINT, 0, 0, 0)
        if os.getppid() != parent:  # boom-demo died before prctl took effect
            os._exit(130)

    return preexec


class Stopper:
    """SIGINT and SIGTERM to boom-demo: each is passed on to the node as one SIGINT, and the
    first ends the scenario. A flag, not an exception: the loops below look at it at least
    every 0.1 s, and rclpy's spin is never torn by an exception raised inside it."""

    def __init__(self, node: subprocess.Popen) -> None:
        self.node = node
        self.received: list[int] = []
        self._previous = {sig: signal.signal(sig, self._on_signal) for sig in STOP_SIGNALS}

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        self.received.append(signum)
        if self.node.poll() is None:
            self.node.send_signal(signal.SIGINT)

    @property
    def stopped(self) -> bool:
        return bool(self.received)

    def stop_node(self) -> None:
        """SIGINT to the node unless a signal of the user's was passed on already."""
        if not self.received and self.node.poll() is None:
            self.node.send_signal(signal.SIGINT)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


def main(argv: list[str] | None = None) -> int:
    return run_main("boom-demo", lambda: demo(argv))


def _ended(status: int) -> str:
    return f"was killed by {signal.Signals(-status).name}" if status < 0 else f"exited with status {status}"


def _node_failed(status: int, when: str) -> int:
    """The exit status for a node that ended by itself ``when``: the node's own 1 or 2 after its
    own one-line error (nothing more to say), else one line here and 1."""
    if status in (1, 2):
        return status
    print(f"boom-demo: error: boom_sim {_ended(status)} {when}", file=sys.stderr)
    return 1


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
        raise ConfigError("the boom_sim executable is not on PATH (run through tools/with-env)")
    cmd = [node_exe, "--ros-args", "-p", f"record_folder:={args.bags}"]
    if args.params_file:
        cmd += ["--params-file", args.params_file]
    # its own process group: a terminal's Ctrl-C reaches the node once, passed on by Stopper
    node_proc = subprocess.Popen(cmd, env=os.environ.copy(), process_group=0, preexec_fn=_die_with_parent())
    stopper = Stopper(node_proc)
    try:
        status = _drive(node_proc, stopper, args.duration)
    finally:  # also when driving failed: the node finishes its bag before boom-demo ends
        stopper.stop_node()
        node_status = node_proc.wait()  # as long as the node takes; signals meanwhile are passed on
        stopper.restore()
    if status is not None:
        return status
    new_bags = sorted(set(args.bags.glob("*_boom_sim")) - before)
    if stopper.stopped:
        name = signal.Signals(stopper.received[0]).name
        where = f"the run so far is in {new_bags[-1]} (boom-analyze analyses it)" if new_bags else "no bag was recorded"
        print(f"boom-demo: error: stopped by {name}; {where}", file=sys.stderr)
        return 130
    if node_status not in (0, 130, -signal.SIGINT):
        return _node_failed(node_status, "while it stopped")
    if not new_bags:
        print(f"boom-demo: error: boom_sim recorded no bag in {args.bags}", file=sys.stderr)
        return 1
    return run_main("boom-analyze", lambda: _analyze(new_bags[-1]))


def _analyze(bag: Path) -> int:
    """The new bag analysed as ``boom-analyze BAG`` does it (its output and its errors' lines)."""
    out = default_results_folder(bag)
    print(report(analyze([bag], out), out))
    return 0


def _drive(node_proc: subprocess.Popen, stopper: Stopper, duration_s: float) -> int | None:
    """Wait for the node's first state, then publish the scenario for ``duration_s``, printing
    the state twice a second. None when done or stopped; an exit status when the node ended."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Stopper handles the signals
    driver = ScenarioDriver(CYCLE)
    try:
        print(
            "boom-demo: starting boom_sim (a start without the compiled model in the cache compiles it: a minute "
            "on a busy machine)",
            file=sys.stderr,
        )
        while driver.state is None and not stopper.stopped:  # as long as the node runs: no deadline
            rclpy.spin_once(driver, timeout_sec=0.1)
            if (status := node_proc.poll()) is not None:
                return _node_failed(status, "before it started")
        if stopper.stopped:
            return None
        print(" t [s]  opening  q1 [m]  alpha [deg]  p1 [MPa]  p2 [MPa]  energy [kJ]", flush=True)
        start = time.monotonic()
        next_print = 0.0
        while (t := time.monotonic() - start) < duration_s and not stopper.stopped:
            if (status := node_proc.poll()) is not None:
                return _node_failed(status, "during the scenario")
            u = driver.send(t)
            rclpy.spin_once(driver, timeout_sec=0.02)
            if t >= next_print and driver.state is not None:
                s = driver.state
                print(
                    f"{t:6.1f}  {u:+7.2f}  {s.rod_position_m:6.4f}  {s.boom_angle_rad * 57.29578:11.2f}  "
                    f"{s.piston_pressure_pa / 1e6:8.2f}  {s.rod_pressure_pa / 1e6:8.2f}  "
                    f"{s.supply_energy_j / 1e3:11.2f}",
                    flush=True,
                )
                next_print += 0.5
        return None
    finally:
        driver.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
