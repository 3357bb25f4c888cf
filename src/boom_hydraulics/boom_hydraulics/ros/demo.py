"""``boom-demo``: start the node, drive it through a work cycle, report what it does.

The node runs as its own process through its real entry point and records the run to a bag
under ``bags/``, which this command then analyses (boom-analyze: signals, metrics, plots).
The scenario (``--scenario``) reaches the node the way a user's would:

- ``cycle`` (the default): lift, hold, lower, hold (9 s), as ValveCommand openings on the
  node's ``valve_command`` topic, the path of a user's ``ros2 topic pub``;
- ``loader`` or ``loader:SEED``: the loader crane's work cycle of ``boom-sim --profile`` and
  ``boom-sweep --scenario`` (18.5 s; SEED an operator's variation): MoveBoom goals to the
  cycle's angles on ``/boom_sim/move_boom`` at its times, and the payload released by
  setting the node's ``payload_mass_kg`` (to that share of the params file's) at the
  release. It needs ``mode: physical``.

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
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

import rclpy
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from boom_hydraulics_msgs.action import MoveBoom
from boom_hydraulics_msgs.msg import DriveState, ValveCommand

from ..analysis.recordings import analyze, default_results_folder, report
from ..errors import ConfigError
from ..model import config
from ..model.parameters import Parameters
from ..programs import RaisingParser, run_main, summary
from ..solve import commands, duty_cycles
from ..solve.commands import CYCLE
from .shutdown import shut_down

#: The scenarios by name (``--scenario``; ``loader:SEED`` too).
SCENARIOS = ("cycle", *duty_cycles.CYCLES)
#: The node whose action and parameters a work cycle uses (boom_sim's default name).
NODE = "boom_sim"


@dataclass(frozen=True)
class WorkCycle:
    """A work cycle as the node takes it: at each of ``goal_times_s`` a MoveBoom goal to the
    matching angle (rad), and at each of ``payload_times_s`` ``payload_mass_kg`` set to the
    matching mass (kg); times from the scenario's start."""

    goal_times_s: tuple[float, ...]
    goal_angles_rad: tuple[float, ...]
    payload_times_s: tuple[float, ...]
    payload_masses_kg: tuple[float, ...]
    duration_s: float


def plan(text: str, params_file: str | None) -> tuple[tuple[tuple[float, float], ...] | WorkCycle, float]:
    """The scenario ``text`` for the node of ``params_file`` (read only for a work cycle, whose
    angles and payload are the boom's): the openings of ``cycle`` (time s, opening) or a
    :class:`WorkCycle`; and its length, s."""
    if text == "cycle":
        return CYCLE, 9.0
    if text.partition(":")[0] not in duty_cycles.CYCLES:
        raise ConfigError(f"unknown --scenario {text!r}; choose {', '.join(SCENARIOS)} or loader:SEED")
    params = config.load(Path(params_file)) if params_file else Parameters()
    if params.mode != "physical":
        raise ConfigError(
            f"--scenario {text} changes the payload within the cycle, which needs mode: physical (the params file "
            f"sets mode: {params.mode})"
        )
    seed = commands.loader_seed(text)
    given = duty_cycles.loader(params, seed)
    cycle = WorkCycle(
        tuple(given["command_times_s"]),
        tuple(given["command_angles_rad"]),
        tuple(given["command_payload_times_s"]),
        tuple(share * params.payload_mass_kg for share in given["command_payload_fractions"]),
        duty_cycles.loader_duration_s(seed),
    )
    return cycle, cycle.duration_s


class ScenarioDriver(Node):
    """Drives the node through the scenario and keeps the latest DriveState: a cycle's
    openings at 50 Hz, or a work cycle's goals and payload changes, each once at its time."""

    def __init__(self, scenario: tuple[tuple[float, float], ...] | WorkCycle) -> None:
        super().__init__("boom_demo")
        self.scenario = scenario
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(DriveState, "drive_state", self.on_state, qos)
        self.state: DriveState | None = None
        self.refused: list[str] = []  # what the node refused, one line each
        if isinstance(scenario, WorkCycle):
            self.moves = ActionClient(self, MoveBoom, f"{NODE}/move_boom")
            self.payload = AsyncParameterClient(self, NODE)
            self._goals_sent = self._payloads_set = 0
        else:
            self.pub = self.create_publisher(ValveCommand, "valve_command", qos)

    def on_state(self, msg: DriveState) -> None:
        self.state = msg

    def ready(self) -> bool:
        """Whether the node has published its state (and serves its goals and parameters)."""
        if self.state is None:
            return False
        if isinstance(self.scenario, WorkCycle):
            return self.moves.server_is_ready() and self.payload.services_are_ready()
        return True

    def opening_at(self, t: float) -> float:
        u = 0.0
        for start, value in self.scenario:
            if t >= start:
                u = value
        return u

    def act(self, t: float) -> float:
        """What the scenario does at ``t`` s from its start; the opening sent, or the node's
        valve command where its controller drives the valve."""
        if not isinstance(self.scenario, WorkCycle):
            msg = ValveCommand()
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.opening = self.opening_at(t)
            self.pub.publish(msg)
            return msg.opening
        cycle = self.scenario
        while self._goals_sent < len(cycle.goal_times_s) and t >= cycle.goal_times_s[self._goals_sent]:
            goal = MoveBoom.Goal(target_angle_rad=cycle.goal_angles_rad[self._goals_sent])  # node's speed
            self.moves.send_goal_async(goal).add_done_callback(self._on_goal_answer)
            self._goals_sent += 1
        while self._payloads_set < len(cycle.payload_times_s) and t >= cycle.payload_times_s[self._payloads_set]:
            mass = Parameter("payload_mass_kg", value=float(cycle.payload_masses_kg[self._payloads_set]))
            self.payload.set_parameters([mass]).add_done_callback(self._on_parameters_answer)
            self._payloads_set += 1
        return float(self.state.valve_command) if self.state is not None else 0.0

    def _on_goal_answer(self, future: Future) -> None:
        if not future.result().accepted:
            self.refused.append("boom_sim rejected a move of the work cycle (its log says why)")

    def _on_parameters_answer(self, future: Future) -> None:
        for result in future.result().results:
            if not result.successful:
                self.refused.append(f"boom_sim refused the payload change: {result.reason}")


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
    parser.add_argument(
        "--scenario",
        default="cycle",
        help="cycle (default): lift, hold, lower, hold by valve openings; loader: a loader crane's work cycle by "
        "MoveBoom goals and a payload change (physical mode); loader:SEED: an operator's variation of it",
    )
    parser.add_argument("--duration", type=float, help="how long to drive the node, s (default: the scenario's length)")
    parser.add_argument("--bags", type=Path, default=Path("bags"), help="folder the node records into (default bags)")
    args = parser.parse_args(argv)
    scenario, length_s = plan(args.scenario, args.params_file)
    duration_s = length_s if args.duration is None else args.duration
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration_s:g}")
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
        status = _drive(node_proc, stopper, scenario, duration_s)
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


def _drive(
    node_proc: subprocess.Popen, stopper: Stopper, scenario: tuple[tuple[float, float], ...] | WorkCycle,
    duration_s: float,
) -> int | None:  # fmt: skip
    """Wait for the node's first state, then drive it through ``scenario`` for ``duration_s``,
    printing the state twice a second. None when done or stopped; an exit status when the
    node ended or refused a step of the scenario."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Stopper handles the signals
    driver = ScenarioDriver(scenario)
    try:
        print(
            "boom-demo: starting boom_sim (a start without the compiled model in the cache compiles it: a minute "
            "on a busy machine)",
            file=sys.stderr,
        )
        while not driver.ready() and not stopper.stopped:  # as long as the node runs: no deadline
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
            u = driver.act(t)
            rclpy.spin_once(driver, timeout_sec=0.02)
            if driver.refused:
                print(f"boom-demo: error: {driver.refused[0]}", file=sys.stderr)
                return 1
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
        shut_down()


if __name__ == "__main__":
    sys.exit(main())
