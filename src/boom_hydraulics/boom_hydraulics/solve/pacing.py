"""Pacing: simulated time tied to a steady clock, tick by tick. No ROS here.

The node ticks at ``rate_hz`` of wall time. At each tick, :meth:`Pacer.due` says how many
physics steps bring simulated time to where the steady clock says it should be (times the
real-time factor); a late tick therefore catches up. A backlog larger than
``max_catch_up_s`` is not worked off: it is dropped (the origin moves on), counted, and
reported, so the node stays responsive instead of running ever later. At real-time factor
0 every tick takes one tick's worth of steps, as fast as the caller ticks.

Following a clock that other nodes share (``drop_backlog=False``), a backlog is never given
up: simulated time must stay the clock's. A tick still takes at most ``max_catch_up_s``
worth of steps, and the rest waits for the next ticks.

:meth:`Pacer.restart` ties the clock afresh to the state as it is: at start, at a resume
and at a new real-time factor. :meth:`Pacer.rebase` keeps the tie and only counts steps
afresh, after a reset or another parameter change (a new time step changes what a step
count means, not where simulated time is due; a reset counts steps from 0 again, so it
gives the count before it and the count after).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Tick:
    """What one tick is to do."""

    steps: int  # physics steps to take now
    dropped_s: float = 0.0  # wall seconds of backlog given up at this tick (0: none)


class Pacer:
    """How many steps each tick takes to follow a steady clock (``wall_s``: e.g. time.monotonic())."""

    def __init__(
        self, rate_hz: float, real_time_factor: float, max_catch_up_s: float, drop_backlog: bool = True
    ) -> None:
        self.rate_hz = rate_hz
        self.drop_backlog = drop_backlog
        self.real_time_factor = real_time_factor
        self.max_catch_up_s = max_catch_up_s
        self.wall_origin_s = 0.0
        self.origin_steps = 0
        self.lag_s = 0.0  # backlog beyond one tick at the last tick, in wall seconds
        self.clock_error_s = 0.0  # how far simulated time trailed the clock after the last tick
        self.late_ticks = 0  # ticks that dropped a backlog since the caller last read it
        self._elapsed_s = 0.0

    def restart(self, wall_s: float, step_count: int) -> None:
        """Simulated time follows the clock from here: ``step_count`` steps taken at ``wall_s``."""
        self.wall_origin_s = wall_s
        self.origin_steps = step_count

    def rebase(self, step_count: int, dt_s: float, counted_from: int | None = None) -> None:
        """Count steps afresh without moving the tie between the clock and simulated time:
        ``step_count`` steps of ``dt_s`` were taken when the change came, and the step count
        goes on from ``counted_from`` (default ``step_count``; 0 after a reset, which counts
        steps from 0 again). After a reset or a parameter change, which take no simulated
        time, simulated time is due where it was."""
        if self.real_time_factor > 0:
            self.wall_origin_s += (step_count - self.origin_steps) * dt_s / self.real_time_factor
        self.origin_steps = step_count if counted_from is None else counted_from

    def per_tick(self, dt_s: float) -> int:
        """Steps in one tick of simulated time at time step ``dt_s``."""
        return max(1, round(1.0 / (self.rate_hz * dt_s)))

    def due(self, wall_s: float, step_count: int, dt_s: float) -> Tick:
        """The steps due at ``wall_s`` when ``step_count`` steps of ``dt_s`` have been taken."""
        per_tick = self.per_tick(dt_s)
        rtf = self.real_time_factor
        if rtf == 0:
            return Tick(per_tick)
        self._elapsed_s = (wall_s - self.wall_origin_s) * rtf  # simulated s due by now
        steps = int(self._elapsed_s / dt_s + 1e-9) - (step_count - self.origin_steps)
        self.lag_s = max(0.0, (steps - per_tick) * dt_s) / rtf
        max_steps = max(per_tick, round(self.max_catch_up_s * rtf / dt_s))
        if steps <= max_steps:
            return Tick(steps)
        self.late_ticks += 1  # cannot keep up: work off what we may, drop the rest (or keep it)
        if not self.drop_backlog:
            return Tick(max_steps)
        dropped_s = (steps - max_steps) * dt_s / rtf
        self.wall_origin_s += dropped_s
        return Tick(max_steps, dropped_s)

    def settled(self, step_count: int, dt_s: float) -> None:
        """After the tick's steps: how far simulated time trailed the clock at this tick, in
        wall seconds (a dropped backlog counts, at the tick that dropped it)."""
        if self.real_time_factor > 0:
            done_s = (step_count - self.origin_steps) * dt_s
            self.clock_error_s = (self._elapsed_s - done_s) / self.real_time_factor
