"""``boom-demo``: start the node, drive it through a work cycle, report what it does.

The node runs as its own process through its real entry point and records the run to a bag
under ``bags/``, which this command then analyses (boom-analyze: signals, metrics, plots).
The scenario (``--scenario``) reaches the node the way a user's would:

- ``cycle`` (the default): lift, hold, lower, hold (9 s), as ValveCommand openings on the
  node's ``valve_command`` topic, the path of a user's ``ros2 topic pub``. Each is stamped on
  the node's clock (the stamps of its DriveStates: ROS time, or simulated time with
  ``publish_clock``) at its instant of the cycle, and sent a little ahead of it: the node
  applies each at its stamp (docs/ros-api.md, "Command stamps"), so the drive follows the
  same trajectory on any machine, however late a message arrives;
- ``loader`` or ``loader:SEED``: the loader crane's work cycle of ``boom-sim --profile`` and
  ``boom-sweep --scenario`` (18.5 s; SEED an operator's variation): MoveBoom goals to the
  cycle's angles on ``/boom_sim/move_boom`` at its times, and the payload released by
  setting the node's ``payload_mass_kg`` (to that share of the params file's) at the
  release. It needs ``mode: physical``.

The scenario starts half a second of the node's clock after the node's time origin, the
instant of its simulated time 0 (moved on to an instant of its energy ledger), and lasts
until the node's clock has passed its end; the analysis covers that window of the node's
clock alone (the node runs longer around it: its start, its stop). A cycle whose commands
the node received but whose valve did not follow them throughout is one line and exit status
1.

The node runs in a ROS domain of boom-demo's own (:mod:`.domains`), unless ROS_DOMAIN_ID is
set, so that two demos on one machine do not take each other's commands.

Stopping: Ctrl-C or SIGTERM ends the scenario; each is passed on to the node as one SIGINT
(the node runs in its own process group, so a terminal's Ctrl-C reaches it once, through
here), and boom-demo waits for the node to finish its bag, then exits 130 (SIGINT) or 143
(SIGTERM) naming the bag. If boom-demo is killed, the node gets SIGINT from the kernel
(Linux: PR_SET_PDEATHSIG) and still finishes its bag. boom-demo waits for the node to start
for as long as it runs: a start that finds no compiled model in the cache (``make setup``
fills it) compiles it, which takes long on a busy machine.
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
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
import rclpy
from rcl_interfaces.msg import Log
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from boom_hydraulics_msgs.action import MoveBoom
from boom_hydraulics_msgs.msg import DriveState, EnergyLedger, ValveCommand

from ..analysis import windows
from ..analysis.recordings import default_results_folder, report
from ..bags.energy import ledger_every
from ..errors import ConfigError
from ..model import config
from ..model.parameters import Parameters
from ..programs import RaisingParser, run_main, summary
from ..solve import commands, duty_cycles
from ..solve.command_queue import valve_opening
from ..solve.commands import CYCLE
from . import domains
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


#: How far ahead of the node's clock each of the cycle's commands is sent, ns, and sent again:
#: a delivery later than this makes no difference (each waits for its stamp), and one would be
#: stale (refused) only if the node's clock went on by this and the command timeout before it
#: arrived. The node's subscription is best effort (the last 5 kept): a command lost on a busy
#: machine is lost twice only if its copy, sent a fifth of a second later, is lost too. Less
#: than :data:`LEAD_NS`: the first commands are not sent in one burst.
AHEAD_NS = (300_000_000, 100_000_000)
#: The most commands sent at one turn of boom-demo's loop (which turns at every state, 100 Hz).
BURST = 2
#: The cycle's command periods, ns, longest first: the cycle's openings change on tenths of a
#: second, and the valve holds an opening until the next command, for command_timeout_s; the
#: longest period within a third of the params file's command_timeout_s is taken (10 Hz for
#: the default 0.5 s).
PERIODS_NS = (100_000_000, 50_000_000, 20_000_000, 10_000_000)
#: How long after the node's first state the scenario starts on its clock, ns.
LEAD_NS = 500_000_000
#: How long after the node's first state the scenario's start is settled, ns: by then an energy
#: ledger message (10 Hz) has come, and the start moves onto the instants of its messages, so
#: that the cycle's window begins and ends at one (its figures then need no carrying on).
#: Less than LEAD_NS - max(AHEAD_NS): no command is sent before.
SETTLE_NS = 150_000_000
#: How many of the node's publishing periods the served clock may run ahead of the node's
#: latest state (lockstep): a node starved on a busy machine wakes to a clock at most this far
#: on, so that its executor has taken the commands due before it steps past their stamps (it
#: takes one message per topic per turn; the clock it would see otherwise is the newest,
#: however many commands still wait).
LOCKSTEP_PERIODS = 2
#: How long the clock boom-demo serves may stand where it waits for the node's first state
#: before it runs on, s of wall time (a safety net: the node began its run at the clock's first
#: instant, so its states come before; were its origin later, it would publish none there).
FIRST_STATE_WAIT_S = 30.0


class ScenarioDriver(Node):
    """Drives the node through the scenario and keeps the latest DriveState and the node's
    clock (its stamps): a cycle's openings at 50 Hz, each stamped at its instant of the cycle
    on the node's clock and sent :data:`AHEAD_NS` ahead of it, or a work cycle's goals and
    payload changes, each once at its time of the node's clock."""

    def __init__(
        self,
        scenario: tuple[tuple[float, float], ...] | WorkCycle,
        serve_clock: bool,
        period_ns: int,
        state_period_ns: int,
        recording: Callable[[], bool] = lambda: True,
    ) -> None:
        super().__init__("boom_demo")
        self.recording = recording  # whether the node has begun its run (its bag is there)
        self.scenario = scenario
        self.period_ns = period_ns
        self.state_period_ns = state_period_ns  # how often the node publishes its state, ns of its clock
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        # the node's clock, where boom-demo serves it: real time from now, as a simulator's /clock
        self.clock_pub = (
            self.create_publisher(Clock, "/clock", QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
            if serve_clock
            else None
        )
        self._clock_origin = (time.time_ns(), time.monotonic_ns())
        self._clock_ns = 0  # the /clock served last (it never goes back)
        # the served clock stands at its first instant until discovery has matched the node (see
        # discovered()) and the node has begun its run (its first /clock: it opens its bag then), so
        # that the node takes that instant as its time origin, whatever its start's timing
        self._held = serve_clock
        self._capped_at, self._uncapped = 0.0, False  # see clock_limit_ns
        # the node's time origin, the scenario's time base (see origin_of): its first state's stamp
        # where the node's origin is not known
        self.first_ns: int | None = None
        self.states = self.create_subscription(DriveState, "drive_state", self.on_state, qos)
        logs = QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.create_subscription(Log, "/rosout", self.on_log, logs)
        self.node_error: str | None = None  # the first error the node logged: it stopped stepping
        self.state: DriveState | None = None
        self.now_ns = 0  # the node's clock: the latest stamp of its states
        self.start_ns = self.end_ns = 0  # the scenario's window on the node's clock (set by begin())
        self.ledger_ns: int | None = None  # the stamp of the node's latest energy ledger
        self._settle_at_ns: int | None = None  # when the start is settled (see SETTLE_NS)
        self._duration_ns = self._ledger_period_ns = 0
        self.create_subscription(EnergyLedger, f"{NODE}/energy", self.on_ledger, qos)
        self.sent = [0, 0]  # cycle commands sent, and sent again
        self.refused: list[str] = []  # what the node refused, one line each
        if isinstance(scenario, WorkCycle):
            self.moves = ActionClient(self, MoveBoom, f"{NODE}/move_boom")
            self.payload = AsyncParameterClient(self, NODE)
            self._goals_sent = self._payloads_set = 0
        else:
            self.pub = self.create_publisher(ValveCommand, "valve_command", qos)

    def tick_clock(self) -> None:
        """Publish /clock (where boom-demo serves it): real time since boom-demo started it, held
        at :meth:`clock_limit_ns` while boom-demo or the node is behind (a busy machine), so that
        the node never reaches a command's stamp before it has the command."""
        if self.clock_pub is not None:
            if self._held and self.discovered() and self.recording():  # the clock runs on from its first instant
                self._held, self._clock_origin = False, (self._clock_origin[0], time.monotonic_ns())
            origin_ns, steady_ns = self._clock_origin
            now_ns = origin_ns if self._held else origin_ns + time.monotonic_ns() - steady_ns
            limit = self.clock_limit_ns()
            self._clock_ns = max(self._clock_ns, now_ns if limit is None else min(now_ns, limit))
            if self.first_ns is None and limit is not None and self._clock_ns >= limit:
                self._capped_at = self._capped_at or time.monotonic()
                self._uncapped = time.monotonic() - self._capped_at > FIRST_STATE_WAIT_S
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(self._clock_ns, 1_000_000_000)
            self.clock_pub.publish(msg)

    def clock_limit_ns(self) -> int | None:
        """How far the served clock may go now (None: no limit): :data:`LOCKSTEP_PERIODS` of the
        node's publishing beyond its latest state, and before the scenario begins, to
        the scenario's start less the longest of :data:`AHEAD_NS` (before the node's first state
        has come, the start from the clock's first instant, or the node's first publishing
        instant where that is later, unless the node has published nothing for
        :data:`FIRST_STATE_WAIT_S` there); while a cycle's commands are sent, to the stamp of
        the last one sent. A work cycle's goals are not stamped: only the lockstep once it began."""
        if self.first_ns is None:  # (the node's states at most to there, before boom-demo has one)
            if self.clock_pub is None or self._uncapped:
                return None
            return self._clock_origin[0] + max(LEAD_NS - max(AHEAD_NS), self.state_period_ns)
        lockstep = self.now_ns + LOCKSTEP_PERIODS * self.state_period_ns
        if not self.start_ns or self._settle_at_ns is not None:  # (held until the start is settled)
            return min(lockstep, (self.start_ns or self.first_ns + LEAD_NS) - max(AHEAD_NS))
        if isinstance(self.scenario, WorkCycle):
            return lockstep
        next_ns = self.start_ns + self.sent[0] * self.period_ns
        return lockstep if next_ns > self.end_ns else min(lockstep, next_ns - self.period_ns)

    def on_log(self, msg: Log) -> None:
        if msg.name == NODE and msg.level >= Log.ERROR and self.node_error is None:
            self.node_error = msg.msg

    def on_state(self, msg: DriveState) -> None:
        self.state = msg
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.now_ns = max(self.now_ns, stamp_ns)
        if self.first_ns is None:
            self.first_ns = self.origin_of(stamp_ns)

    def origin_of(self, stamp_ns: int) -> int:
        """The node's time origin, from the stamp of the first of its states boom-demo received.
        The node publishes a state every ``state_period_ns`` of simulated time from its origin
        (docs/ros-api.md): on its own clock (publish_clock) the origin is 0; on the clock
        boom-demo serves, it is the instant the clock stood at until discovery matched, which the
        node took as its first /clock (its run began there). A first state off that grid (a node
        whose origin is not known) leaves the stamp itself. So the scenario starts at
        the same simulated time of the node's, whichever of its states came first (discovery
        may match after the node's first states: the boom's settling at the start then moved
        a figure's last digit)."""
        origin_ns = self._clock_origin[0] if self.clock_pub is not None else 0
        on_grid = stamp_ns >= origin_ns and (stamp_ns - origin_ns) % self.state_period_ns == 0
        return origin_ns if on_grid else stamp_ns

    def discovered(self) -> bool:
        """Whether discovery has matched the node with boom-demo: its clock (where served) and
        state, and its valve_command subscription or move_boom action and parameter services."""
        if self.clock_pub is not None and self.clock_pub.get_subscription_count() == 0:
            return False
        if self.states.get_publisher_count() == 0:
            return False
        if isinstance(self.scenario, WorkCycle):
            return self.moves.server_is_ready() and self.payload.services_are_ready()
        return self.pub.get_subscription_count() > 0

    def ready(self) -> bool:
        """Whether the node has published its state and takes the scenario: serves its goals and
        parameters, or has its valve_command subscription matched to boom-demo's publisher (the
        cycle's first commands, sent before discovery had matched them, were lost, and one of
        the first stamp's arrived after it: 'the valve followed them in only 99 %')."""
        return self.state is not None and self.discovered()

    def on_ledger(self, msg: EnergyLedger) -> None:
        self.ledger_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    def begin(self, duration_ns: int, ledger_period_ns: int) -> None:
        """The scenario starts :data:`LEAD_NS` after the node's time origin (:meth:`origin_of`;
        not after whenever boom-demo got to it: the node's state at the start would depend on
        the machine's load), or after its latest state where the node's own clock ran too near
        that start before discovery matched (a busy machine: the first commands would be
        late), moved on to the next instant of the node's energy ledger (every
        ``ledger_period_ns``) once :data:`SETTLE_NS` has passed (see :meth:`settle`), and lasts
        ``duration_ns``."""
        base = self.now_ns if self.first_ns is None else self.first_ns
        if base + LEAD_NS - max(AHEAD_NS) < self.clock_ns():
            base = self.clock_ns()
        self._settle_at_ns = base + SETTLE_NS
        self._duration_ns, self._ledger_period_ns = duration_ns, ledger_period_ns
        self.start_ns = base + LEAD_NS
        self.end_ns = self.start_ns + duration_ns

    def clock_ns(self) -> int:
        """The node's clock as far as boom-demo knows it: its latest state's stamp, or the /clock
        boom-demo serves where that is further (a node that publishes its states seldom: the
        served clock, held at :meth:`clock_limit_ns`, reaches where the next commands are due)."""
        return max(self.now_ns, self._clock_ns)

    def settle(self) -> None:
        """Move the start onto the ledger's instants, once, when the first ledger message has
        come (none in paper mode: ``ledger_period_ns`` 0); no command is sent before (their
        stamps are the start's), and the /clock boom-demo serves waits for it."""
        if self._settle_at_ns is None or self.clock_ns() < self._settle_at_ns:
            return
        if self._ledger_period_ns and self.ledger_ns is None:
            return  # (it comes with the node's first states: the clock is held before the start meanwhile)
        self._settle_at_ns = None
        if self.ledger_ns is not None and self._ledger_period_ns:
            period = self._ledger_period_ns
            self.start_ns = self.ledger_ns + -(-(self.start_ns - self.ledger_ns) // period) * period
            self.end_ns = self.start_ns + self._duration_ns

    def elapsed_s(self) -> float:
        """The node's clock since the scenario's start, s."""
        return (self.now_ns - self.start_ns) * 1e-9

    def opening_at(self, t: float) -> float:
        return _opening(self.scenario, t)

    def act(self) -> float:
        """What the scenario does up to the node's clock now; the opening at the node's clock
        now, or the node's valve command where its controller drives the valve."""
        self.settle()
        end_ns = self.end_ns
        t = self.elapsed_s()
        if not isinstance(self.scenario, WorkCycle):
            settled = self._settle_at_ns is None  # (no command before the start is settled)
            for copy, ahead_ns in enumerate(AHEAD_NS if settled else ()):
                for _ in range(BURST):
                    stamp_ns = self.start_ns + self.sent[copy] * self.period_ns
                    if stamp_ns > min(self.clock_ns() + ahead_ns, end_ns):
                        break
                    msg = ValveCommand()
                    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
                    msg.opening = self.opening_at(self.sent[copy] * self.period_ns / 1e9)
                    self.pub.publish(msg)
                    self.sent[copy] += 1
            return self.opening_at(t) if t >= 0 else 0.0
        cycle = self.scenario
        if self._settle_at_ns is not None:
            return float(self.state.valve_command) if self.state is not None else 0.0
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


def _opening(cycle: tuple[tuple[float, float], ...], t: float) -> float:
    """The opening of ``cycle`` ((time s, opening) from each time on) at ``t`` s; 0 before it."""
    u = 0.0
    for start, value in cycle:
        if t >= start:
            u = value
    return u


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


#: boom-demo's exit status when stopped by each signal (docs/cli.md, "Exit statuses").
STOPPED_STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}
#: How long the node's clock may stand still while the scenario runs, s of wall time.
STILL_CLOCK_S = 30.0


def _ended(status: int) -> str:
    return f"was killed by {signal.Signals(-status).name}" if status < 0 else f"exited with status {status}"


def _node_failed(status: int, when: str) -> int:
    """The exit status for a node that ended by itself ``when``: the node's own 1 or 2 after its
    own one-line error (nothing more to say), else one line here and 1."""
    if status in (1, 2):
        return status
    print(f"boom-demo: error: boom_sim {_ended(status)} {when}", file=sys.stderr)
    return 1


def _node_stopped(error: str) -> int:
    """The exit status for a node that logged an error and stopped stepping (it waits for a
    ~/reset that nobody sends): its error in one line, and 1."""
    print(f"boom-demo: error: boom_sim: {error}", file=sys.stderr)
    return 1


@dataclass
class Driven:
    """How driving the node ended: an exit status (None: the scenario ran, or was stopped), the
    scenario's window on the node's clock (ns) and the cycle's commands sent."""

    status: int | None
    start_ns: int = 0
    end_ns: int = 0
    sent: int = 0
    period_ns: int = PERIODS_NS[0]


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
    given = _node_values(args.params_file)
    if given.get("record") is False:  # (the run begins with its bag: the clock boom-demo serves waits for it)
        raise ConfigError(
            f"{args.params_file} sets record: false, but boom-demo analyses the bag the node records: remove it "
            "(or run boom_sim yourself)"
        )

    node_exe = shutil.which("boom_sim")
    if node_exe is None:
        raise ConfigError("the boom_sim executable is not on PATH (run through tools/with-env)")
    domain, own, lock = domains.claim(os.environ)  # this process's rclpy and the node's both read it
    if own:
        print(
            f"boom-demo: boom_sim runs in a ROS domain of its own on this machine, ROS_DOMAIN_ID={domain} "
            "(set ROS_DOMAIN_ID to run it in yours)",
            file=sys.stderr,
        )
    cmd = [node_exe, "--ros-args", "-p", f"record_folder:={args.bags}"]
    if args.params_file:
        cmd += ["--params-file", args.params_file]
    serve_clock = given.get("publish_clock") is not True
    period_ns = command_period_ns(given.get("command_timeout_s"))
    if serve_clock:  # (after the file: the last word)
        cmd += ["-p", "use_sim_time:=true"]
    # its own process group: a terminal's Ctrl-C reaches the node once, passed on by Stopper;
    # it holds the domain's lock too, for as long as it runs
    node_proc = subprocess.Popen(
        cmd, env=os.environ.copy(), process_group=0, preexec_fn=_die_with_parent(), pass_fds=(lock.fileno(),)
    )
    stopper = Stopper(node_proc)
    try:
        ledger_ns = ledger_period_ns(given) if given.get("mode", "physical") != "paper" else 0  # (none in paper mode)
        state_ns = round(1e9 / publish_rate_hz(given))

        def recording() -> bool:  # whether the node has begun its run: its new bag is there
            return bool(set(args.bags.glob("*_boom_sim")) - before)

        driven = _drive(
            node_proc, stopper, scenario, duration_s, serve_clock, (period_ns, state_ns), ledger_ns, recording
        )
    finally:  # also when driving failed: the node finishes its bag before boom-demo ends
        stopper.stop_node()
        node_status = node_proc.wait()  # as long as the node takes; signals meanwhile are passed on
        stopper.restore()
        lock.close()
    if driven.status is not None:
        return driven.status
    new_bags = sorted(set(args.bags.glob("*_boom_sim")) - before)
    if stopper.stopped:
        name = signal.Signals(stopper.received[0]).name
        where = f"the run so far is in {new_bags[-1]} (boom-analyze analyses it)" if new_bags else "no bag was recorded"
        print(f"boom-demo: error: stopped by {name}; {where}", file=sys.stderr)
        return STOPPED_STATUS[signal.Signals(stopper.received[0])]
    if node_status not in (0, 130, -signal.SIGINT):
        return _node_failed(node_status, "while it stopped")
    if not new_bags:
        print(f"boom-demo: error: boom_sim recorded no bag in {args.bags}", file=sys.stderr)
        return 1
    cycle = None if isinstance(scenario, WorkCycle) else scenario
    mode = str(given.get("mode", "physical"))
    return run_main("boom-analyze", lambda: _analyze(new_bags[-1], driven, cycle, mode))


def _node_values(params_file: str | None) -> dict[str, Any]:
    """The values the params file gives the node (none for a file that does not read: the
    node refuses it, in its own words)."""
    if params_file is None:
        return {}
    try:
        return config.read_values(params_file)
    except ConfigError:
        return {}


def publish_rate_hz(given: Mapping[str, Any]) -> float:
    """How often the node publishes its state, Hz of its clock (the default where the file gives no number)."""
    rate = given.get("publish_rate_hz", 100.0)
    return float(rate) if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate > 0 else 100.0


def ledger_period_ns(given: Mapping[str, Any]) -> int:
    """How often the node publishes its energy ledger, ns: every ledger_every(rate) states."""
    rate = publish_rate_hz(given)
    return round(ledger_every(rate) * 1e9 / rate)


def command_period_ns(timeout_s: Any) -> int:
    """The cycle's command period for the node's ``command_timeout_s`` (see :data:`PERIODS_NS`)."""
    if not isinstance(timeout_s, (int, float)) or isinstance(timeout_s, bool) or not timeout_s > 0:
        return PERIODS_NS[0]  # the default, or never (0)
    return next((p for p in PERIODS_NS if p * 3 <= timeout_s * 1e9), PERIODS_NS[-1])


def followed_share(signals: Mapping[str, np.ndarray], opening_at: Callable[[float], float]) -> float:
    """The share of the window's states (``t`` from the cycle's start) whose valve command is
    ``opening_at`` their time: a state shows the command of the step that ends at its stamp, so
    the opening just before it (0.1 us: a step is longer)."""
    t, u = np.asarray(signals["t"]), np.asarray(signals["u"])
    expected = np.array([opening_at(x - 1e-7) for x in t])
    return float(np.mean(u == expected))


def _analyze(bag: Path, driven: Driven, cycle: tuple[tuple[float, float], ...] | None, mode: str) -> int:
    """The scenario's window of the new bag analysed as ``boom-analyze BAG`` analyses a bag
    (its output and its errors' lines); a ``cycle`` whose commands the valve did not follow
    (as the node applies them in ``mode``), or not throughout, is one line and 1."""
    signals = windows.drive_states_in(bag, driven.start_ns, driven.end_ns)
    if (
        cycle is not None
        and (share := followed_share(signals, lambda t: valve_opening(_opening(cycle, t), mode))) < 1.0
    ):
        what = (
            "none of them acted (the valve command stayed 0)"
            if not windows.valve_acted(signals)
            else f"the valve followed them in only {100 * share:.0f} % of the cycle"
        )
        print(
            f"boom-demo: error: boom_sim received the cycle's commands ({driven.sent} sent) but {what}: its log says "
            f"why (a stamp stale on arrival: a clock faster than real time; a command_timeout_s shorter than the "
            f"commands' period, {driven.period_ns / 1e9:g} s); the run is in {bag}",
            file=sys.stderr,
        )
        return 1
    out = default_results_folder(bag)
    print(report(windows.analyze_window(bag, out, driven.start_ns, driven.end_ns, signals), out))
    return 0


def _drive(
    node_proc: subprocess.Popen, stopper: Stopper, scenario: tuple[tuple[float, float], ...] | WorkCycle,
    duration_s: float, serve_clock: bool, periods_ns: tuple[int, int], ledger_period_ns: int,
    recording: Callable[[], bool],
) -> Driven:  # fmt: skip
    """Wait for the node's first state, then drive it through ``scenario`` until its clock has
    passed ``duration_s`` from the scenario's start, printing the state every half second of
    it. The status is None when done or stopped; an exit status when the node ended, refused
    a step of the scenario, or its clock stood still. ``periods_ns``: the cycle's commands' and
    the node's states'; ``recording``: whether the node has begun its run (see ScenarioDriver)."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Stopper handles the signals
    period_ns, state_period_ns = periods_ns
    driver = ScenarioDriver(scenario, serve_clock, period_ns, state_period_ns, recording)
    try:
        print(
            "boom-demo: starting boom_sim (a start without the compiled model in the cache compiles it: a minute "
            "on a busy machine)",
            file=sys.stderr,
        )
        while not driver.ready() and not stopper.stopped:  # as long as the node runs: no deadline
            driver.tick_clock()
            rclpy.spin_once(driver, timeout_sec=0.02)
            if (status := node_proc.poll()) is not None:
                return Driven(_node_failed(status, "before it started"))
            if driver.node_error is not None:
                return Driven(_node_stopped(driver.node_error))
        if stopper.stopped:
            return Driven(None)
        driver.begin(round(duration_s * 1e9), ledger_period_ns)
        driven = Driven(None, period_ns=period_ns)
        print(" t [s]  opening  q1 [m]  alpha [deg]  p1 [MPa]  p2 [MPa]  energy [kJ]", flush=True)
        next_print = 0.0
        clock_seen, clock_moved = driver.now_ns, time.monotonic()
        while driver.now_ns < driver.end_ns and not stopper.stopped:
            if (status := node_proc.poll()) is not None:
                return Driven(_node_failed(status, "during the scenario"))
            driver.tick_clock()
            u = driver.act()
            driven.sent, driven.start_ns, driven.end_ns = driver.sent[0], driver.start_ns, driver.end_ns
            rclpy.spin_once(driver, timeout_sec=0.02)
            if driver.refused:
                print(f"boom-demo: error: {driver.refused[0]}", file=sys.stderr)
                return Driven(1)
            if driver.node_error is not None:
                return Driven(_node_stopped(driver.node_error))
            if driver.now_ns != clock_seen:
                clock_seen, clock_moved = driver.now_ns, time.monotonic()
            elif time.monotonic() - clock_moved > STILL_CLOCK_S:
                print(
                    f"boom-demo: error: boom_sim's clock stood still for {STILL_CLOCK_S:g} s (is it paused: "
                    "start_paused, or following a /clock that nobody publishes: use_sim_time?)",
                    file=sys.stderr,
                )
                return Driven(1)
            t = driver.elapsed_s()
            if t >= next_print and driver.state is not None:
                s = driver.state
                print(
                    f"{t:6.1f}  {u:+7.2f}  {s.rod_position_m:6.4f}  {s.boom_angle_rad * 57.29578:11.2f}  "
                    f"{s.piston_pressure_pa / 1e6:8.2f}  {s.rod_pressure_pa / 1e6:8.2f}  "
                    f"{s.supply_energy_j / 1e3:11.2f}",
                    flush=True,
                )
                next_print += 0.5
        return driven
    finally:
        driver.destroy_node()
        shut_down()


if __name__ == "__main__":
    sys.exit(main())
