"""Valve commands waiting for their simulated time: the node's rule for command stamps.

Rule (documented in docs/ros-api.md, "Command stamps", and ValveCommand.msg):
- A command with a zero stamp, or stamped at or before the current simulated time, takes
  effect at the next physics step.
- A command stamped in the future waits, and takes effect at the first step that starts
  within half a step of its stamp. Commands due at the same step apply in stamp order
  (the last wins).
- At most ``max_pending`` future commands wait; more are refused.
- A command that was already older than the command timeout when it was received is stale
  and refused (:func:`stale`), as ros2_control's controllers ignore a command older than
  their timeout: applied, it would time out before its first step.

With this rule a scenario sent ahead of time gives the same trajectory as ``boom-sim``
with the same commands, however late the messages are delivered or the node's timer fires.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..errors import SimulationError
from .closed_loop import PositionLoop

if TYPE_CHECKING:
    from ..model.setpoints import SetpointPath
    from .batch import SetRun
    from .simulation import Simulator


def valve_opening(opening: float, mode: str) -> float | None:
    """A received opening as applied: None (ignored) if not finite, else clamped to [-1, 1]
    ([0, 1] in paper mode, whose valve only connects pump to piston chamber)."""
    if not math.isfinite(opening):
        return None
    return min(1.0, max(0.0 if mode == "paper" else -1.0, opening))


def stale(stamp_s: float, received_s: float, timeout_s: float) -> bool:
    """Whether a command stamped at ``stamp_s`` and received at ``received_s`` (both in
    simulated time) was already older than the command timeout ``timeout_s`` (0: never stale)."""
    return timeout_s > 0 and received_s - stamp_s >= timeout_s


class CommandQueue:
    """Future valve commands ordered by their simulated time."""

    def __init__(self, max_pending: int = 10_000):
        self.max_pending = max_pending
        self._heap: list[tuple[float, int, float]] = []
        self._order = itertools.count()

    def __len__(self) -> int:
        return len(self._heap)

    def push(self, at_s: float, opening: float) -> bool:
        """Queue ``opening`` for simulated time ``at_s``; False when the queue is full."""
        if len(self._heap) >= self.max_pending:
            return False
        heapq.heappush(self._heap, (at_s, next(self._order), opening))
        return True

    def apply_due(self, t_s: float, dt_s: float, apply: Callable[[float, float], None]) -> None:
        """Apply, in order, every command due at the step that starts at ``t_s``."""
        while self._heap and self._heap[0][0] <= t_s + 0.5 * dt_s:
            at_s, _, opening = heapq.heappop(self._heap)
            apply(opening, at_s)

    def steps_until_next(self, t_s: float, dt_s: float, limit: int) -> int:
        """Steps that may run from ``t_s`` before the next queued command is due (1 .. limit)."""
        if not self._heap:
            return limit
        k = math.ceil((self._heap[0][0] - t_s) / dt_s - 0.5 - 1e-9)
        return max(1, min(limit, k))

    def clear(self) -> None:
        self._heap.clear()


class CommandedDrive:
    """A simulator driven by stamped valve commands, with a spring-centred valve, or by the
    position controller following a setpoint path.

    The stepping rule of the node, without ROS: queued commands apply at their times
    (see the module docstring), and the valve returns to 0 when no command arrived for
    ``timeout_s`` of simulated time (0: never). The node and ``boom-resim`` both use it.

    :meth:`follow` hands the valve to the position controller (closed loop: its opening at
    every step, from the state at the step's start); it holds the path's last angle after its
    end. The controller runs in the run loop, compiled (:meth:`Simulator.following`), as
    ``boom-sim``'s angle scenario runs it. A valve command that applies while the controller
    drives takes over (operator override): the controller lets go and ``on_override`` is called.
    """

    def __init__(self, sim: Simulator, timeout_s: float = 0.0, max_pending: int = 10_000):
        self.sim = sim
        self.timeout_s = timeout_s
        self.queue = CommandQueue(max_pending)
        self.current = 0.0  # the opening applied now
        self.last_command_s: float | None = None
        self.loop: PositionLoop | None = None  # the controller, while it drives the valve
        self.on_override: Callable[[], None] = lambda: None
        self.followed: SetpointPath | None = None  # the path the controller followed in the last advance()
        self._run: SetRun | None = None  # the controller's run, while it drives ...
        self._run_of: tuple = ()  # ... for this controller, path and parameters ...
        self._run_left: list[float] | None = None  # ... and the state it left (see _following)

    def push(self, at_s: float, opening: float) -> bool:
        """Queue ``opening`` for simulated time ``at_s`` (now or earlier: the next step)."""
        return self.queue.push(at_s, opening)

    def reset(self) -> None:
        self.queue.clear()
        self.current = 0.0
        self.last_command_s = None
        self.loop = None
        self.followed = None

    def follow(self, path: SetpointPath) -> None:
        """Drive the valve with the position controller along ``path`` (times in simulated s)."""
        if self.loop is None:
            self.loop = PositionLoop([self.sim.params], path, self.sim.constants)
        else:
            self.loop.restart(path)
        self.queue.clear()  # manual commands waiting for later would take over: the move replaces them
        self.last_command_s = None

    def let_go(self) -> None:
        """The controller stops driving: the valve closes (the load-holding valve holds the boom)."""
        self.loop = None
        self.current = 0.0

    def setpoint(self) -> tuple[float, float]:
        """The controller's setpoint (angle rad, rate rad/s) now; the boom angle at rest when not following."""
        if self.loop is not None:
            return self.loop.path.at(self.sim.t)
        return float(self.sim.outputs()["alpha"]), 0.0

    def _apply(self, opening: float, at_s: float) -> None:
        self.current = opening
        self.last_command_s = at_s
        if self.loop is not None:
            self.loop = None
            self.on_override()

    def parameters_changed(self) -> None:
        """The simulator's parameters changed: the controller takes their gains and constants
        (paper mode has no position control: the controller lets go)."""
        if self.loop is not None and self.sim.params.mode != "physical":
            self.let_go()
        if self.loop is not None:
            path = self.loop.path
            self.loop = PositionLoop([self.sim.params], path, self.sim.constants)

    def _current_run(self) -> SetRun | None:
        """The controller's run, if it is still the one to go on with: None when the controller,
        its path, the parameters or the state are no longer those it went on with (a new goal,
        new parameters, a reset), or when it ran its FOLLOW_HORIZON_S."""
        loop, sim = self.loop, self.sim
        if self._run is None or loop is None or sim.y is not self._run_left or self._run.done >= self._run.passes:
            return None
        return self._run if all(a is b for a, b in zip((loop, loop.path, sim.params), self._run_of)) else None

    def _following(self) -> SetRun:
        """The run of the controller that drives now, begun afresh from the current state where
        :meth:`_current_run` has none."""
        run = self._current_run()
        if run is None:
            loop = self.loop
            assert loop is not None
            run = self._run = self.sim.following(loop)
            self._run_of = (loop, loop.path, self.sim.params)
        return run

    @property
    def holding(self) -> bool:
        """Whether the controller holds its path's end within its dead-band as it gives the
        next step's opening: the move settled (model.control.position_command). False when it
        does not drive."""
        run = self._current_run()
        return run is not None and run.holding(0)

    def advance(self, steps: int) -> None:
        """Take ``steps`` physics steps; raises SimulationError as Simulator.step does."""
        dt = self.sim.params.time_step_s
        self.followed = None
        while steps > 0:
            t = self.sim.t
            self.queue.apply_due(t, dt, self._apply)
            chunk = self.queue.steps_until_next(t, dt, steps)
            if self.loop is not None:  # closed loop: the controller's opening at every step, up to the next command
                self.followed = self.loop.path
                run = self._following()
                before = self.sim.step_count
                try:
                    self.sim.go_on(run, chunk)
                except SimulationError:
                    self._run = None  # a failed run goes no further
                    raise
                finally:
                    self.current = self.sim.u  # the opening of the last step taken (or of the one that failed)
                self._run_left = self.sim.y  # the state is the run's own
                steps -= self.sim.step_count - before  # (fewer than chunk where the run reached its end)
                continue
            if self.timeout_s > 0 and self.current != 0.0 and self.last_command_s is not None:
                deadline = self.last_command_s + self.timeout_s
                if t + 0.5 * dt >= deadline:
                    self.current = 0.0
                else:
                    chunk = max(1, min(chunk, math.ceil((deadline - t) / dt - 0.5 - 1e-9)))
            self.sim.step(self.current, chunk)
            steps -= chunk
