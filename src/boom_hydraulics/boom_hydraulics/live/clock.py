"""A live run's clock: simulated time follows the steady clock times the real-time factor.

As the node on its own clock (its SYSTEM mode, docs/ros-api.md): the ticks come at
``rate_hz`` of wall time, each takes the steps the :class:`~..solve.pacing.Pacer` says are
due (a late tick catches up, a backlog beyond ``max_catch_up_s`` is dropped and counted);
stamps are the system clock (ROS time without a ROS graph), the state's stamp its simulated
instant mapped through the time origin at real-time factor 1, and the time it is published
at any other factor. Real-time factor 0 runs the ticks back to back, as fast as they go.
"""

from __future__ import annotations

import threading
import time

from ..solve.pacing import Pacer, Tick
from ..solve.simulation import Simulator


class LiveClock:
    """The time origin and the pacing of one live run of a simulator ``sim``."""

    def __init__(self, sim: Simulator, rate_hz: float, real_time_factor: float, max_catch_up_s: float) -> None:
        self.sim = sim
        self.rate_hz = rate_hz
        self.rtf = real_time_factor
        self.pacer = Pacer(rate_hz, real_time_factor, max_catch_up_s)
        self.origin_ns = 0  # the system-clock time of simulated time 0 (command stamps map through it)
        self.origin_shift_s = 0.0  # how far dropped backlogs moved it
        self._deadline = time.monotonic()

    def restart(self) -> None:
        """Tie simulated time to the clock from now on (at the start)."""
        self.pacer.restart(time.monotonic(), self.sim.step_count)
        self.origin_ns = time.time_ns() - round(self.sim.t * 1e9)
        self._deadline = time.monotonic()

    def rebase(self, dt_before_s: float, steps_before: int) -> None:
        """Time runs on, tied to the clock as before (a parameter change takes no simulated time):
        ``steps_before`` steps of ``dt_before_s`` were taken before the change, and the count goes
        on from the simulator's now (0 after a change of mode, which resets the state)."""
        self.pacer.rebase(steps_before, dt_before_s, self.sim.step_count)

    def due(self) -> Tick:
        """The steps due now; a dropped backlog moves the origin of command stamps along."""
        sim = self.sim
        tick = self.pacer.due(time.monotonic(), sim.step_count, sim.params.time_step_s)
        if tick.dropped_s:
            self.origin_ns += round(tick.dropped_s * 1e9)
            self.origin_shift_s += tick.dropped_s
        return tick

    def wait(self, stopping: threading.Event) -> None:
        """Until the next tick is due (at once, back to back, at real-time factor 0), or ``stopping`` is set."""
        if self.rtf == 0:
            return
        self._deadline = max(self._deadline + 1.0 / self.rate_hz, time.monotonic() - 1.0 / self.rate_hz)
        stopping.wait(max(0.0, self._deadline - time.monotonic()))

    @staticmethod
    def now_ns() -> int:
        """Now on the run's clock: the system clock."""
        return time.time_ns()

    def sim_instant_ns(self) -> int:
        """The clock time of the simulated instant now."""
        return self.origin_ns + round(self.sim.t * 1e9)

    def state_stamp_ns(self) -> int:
        """The header stamp of the state now: its simulated instant at real-time factor 1,
        else the time it is published (simulated time runs at another pace than the clock)."""
        return self.sim_instant_ns() if self.rtf == 1.0 else self.now_ns()

    def to_sim_s(self, stamp_ns: int) -> float:
        """Simulated time a command stamp (clock ns) means."""
        return (stamp_ns - self.origin_ns) * 1e-9
