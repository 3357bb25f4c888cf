"""The node's clock: which clock simulated time follows, and how the ticks are paced.

One :class:`ClockMode`, chosen at start (``publish_clock`` and ``use_sim_time`` are start-only):

- ``SYSTEM``: ROS time is the system clock; simulated time follows the steady clock times
  ``real_time_factor`` (0: as fast as possible, ticks back to back). Command stamps are ROS
  time, mapped to simulated time through the time origin (the ROS time of simulated time 0).
- ``PUBLISHED`` (``publish_clock``): as ``SYSTEM``, and the node publishes /clock, which is
  simulated time; command stamps are simulated time.
- ``FOLLOWED`` (``use_sim_time``): simulated time follows the ROS clock (/clock, whoever
  publishes it), at its pace; no /clock yet: no stepping; a jump back is a world reset.

:class:`NodeClock` keeps the time origin and the :class:`Pacer`, and turns the mode into the
three things the node asks: when the next tick is due, how many steps it takes, and the
stamps of what it publishes.
"""

from __future__ import annotations

import enum
import threading
import time
from typing import Any

from rclpy.clock import Clock

from ..errors import ConfigError
from ..solve.pacing import Pacer, Tick
from ..solve.simulation import Simulator

#: A ROS clock that steps back by more than this is a jump back (a world reset), s.
CLOCK_JUMP_S = 1e-3


class ClockMode(enum.Enum):
    """Which clock simulated time follows (see the module docstring)."""

    SYSTEM = "system"
    PUBLISHED = "published"
    FOLLOWED = "followed"

    @classmethod
    def of(cls, publish_clock: bool, use_sim_time: bool) -> ClockMode:
        """The mode of the start parameters; ConfigError for both at once."""
        if use_sim_time and publish_clock:
            raise ConfigError(
                "use_sim_time and publish_clock are both true: this node either follows /clock (use_sim_time, "
                "another node publishes it) or publishes it (publish_clock); set one of them to false"
            )
        return cls.FOLLOWED if use_sim_time else cls.PUBLISHED if publish_clock else cls.SYSTEM


class Follow(enum.Enum):
    """What the ROS clock (FOLLOWED) says at a tick."""

    WAIT = "wait"  # no /clock yet: no stepping
    FIRST = "first"  # the first /clock: the time origin is now
    JUMPED_BACK = "jumped back"  # a world reset: the drive goes back to rest
    ON = "on"


class NodeClock:
    """The time origin and the pacing of one node (see the module docstring)."""

    def __init__(
        self,
        mode: ClockMode,
        ros_clock: Clock,
        sim: Simulator,
        rate_hz: float,
        real_time_factor: float,
        max_catch_up_s: float,
    ) -> None:
        self.mode = mode
        self.ros_clock = ros_clock
        self.sim = sim
        self.rate_hz = rate_hz
        self.rtf = real_time_factor
        # on a shared clock the backlog is worked off, never dropped: simulated time stays the clock's
        self.pacer = Pacer(rate_hz, self.pace_factor(), max_catch_up_s, drop_backlog=mode is not ClockMode.FOLLOWED)
        self.origin_ns = 0  # the node-clock time of simulated time 0 (command stamps map through it)
        self.origin_shift_s = 0.0  # how far dropped backlogs moved the time origin of command stamps
        self.seen_s = 0.0  # the latest ROS time the loop saw (FOLLOWED)
        self.read_s = 0.0  # the ROS time the last :meth:`follow` read
        self.taken_ns = 0  # the /clock the node's executor took last, after the commands before it (FOLLOWED)

    @property
    def follows(self) -> bool:
        return self.mode is ClockMode.FOLLOWED

    @property
    def publishes(self) -> bool:
        return self.mode is ClockMode.PUBLISHED

    @property
    def back_to_back(self) -> bool:
        """Ticks run back to back (real_time_factor 0 on the node's own clock)."""
        return self.rtf == 0 and not self.follows

    def pace_factor(self) -> float:
        """Simulated seconds per second of the clock followed: 1 on the ROS clock."""
        return 1.0 if self.follows else self.rtf

    def take(self, clock_ns: int) -> None:
        """A /clock message, as the node's executor takes it after the command topics' messages
        of the same turn (its subscription is the node's last)."""
        self.taken_ns = clock_ns

    def followed_ns(self) -> int:
        """FOLLOWED: the ROS clock as far as the node may step, ns: no further than the /clock its
        executor has taken after the commands that came before it. On a starved node rclpy's
        clock is the newest /clock while commands sent before it still wait their turn (one
        message per topic per turn of the executor): stepping to it would pass their stamps."""
        return min(self.ros_clock.now().nanoseconds, self.taken_ns)

    def pace_clock_s(self) -> float:
        """The clock simulated time follows: the ROS clock (FOLLOWED) or the steady clock."""
        if self.follows:
            return self.followed_ns() * 1e-9
        return time.monotonic()

    def set_pace(self, rate_hz: float, real_time_factor: float, max_catch_up_s: float) -> None:
        """New node parameters (a new real-time factor also needs :meth:`restart`)."""
        self.rate_hz, self.rtf = rate_hz, real_time_factor
        self.pacer.rate_hz, self.pacer.real_time_factor = rate_hz, self.pace_factor()
        self.pacer.max_catch_up_s = max_catch_up_s

    def restart(self) -> None:
        """Tie simulated time to the clock from now on: at the start (or the first /clock), a
        resume, a new real-time factor and a jump back of the ROS clock."""
        self.pacer.restart(self.pace_clock_s(), self.sim.step_count)
        # command stamps are sim time when the node owns the clock, else ROS time mapped to sim time
        now_ns = self.followed_ns() if self.follows else self.ros_clock.now().nanoseconds
        self.origin_ns = 0 if self.publishes else now_ns - round(self.sim.t * 1e9)
        self.seen_s = now_ns * 1e-9

    def rebase(self, dt_before: float, steps_before: int) -> None:
        """Time runs on from here, tied to the clock as before (a change that takes no simulated
        time): ``steps_before`` steps of ``dt_before`` had been counted when it came, and the
        simulator counts on from its step count now (0 after a reset)."""
        self.pacer.rebase(steps_before, dt_before, self.sim.step_count)

    def follow(self) -> Follow:
        """FOLLOWED: whether the loop may step now, and what the ROS clock did."""
        now = self.read_s = self.followed_ns() * 1e-9
        if now <= 0.0:
            return Follow.WAIT
        if self.seen_s <= 0.0:
            self.restart()
            return Follow.FIRST
        if now < self.seen_s - CLOCK_JUMP_S:
            return Follow.JUMPED_BACK
        self.seen_s = max(self.seen_s, now)
        return Follow.ON

    def due(self) -> Tick:
        """The steps due at this tick; a dropped backlog moves the origin of ROS-time stamps."""
        tick = self.pacer.due(self.pace_clock_s(), self.sim.step_count, self.sim.params.time_step_s)
        if tick.dropped_s and not self.publishes:
            self.origin_ns += round(tick.dropped_s * 1e9)  # ROS-time stamps map to the later sim time
            self.origin_shift_s += tick.dropped_s
        return tick

    def wait_for_tick(self, deadline: float, stopping: threading.Event) -> float:
        """Sleep to the tick after ``deadline`` (monotonic s; back to back: yield only); the new deadline."""
        if self.back_to_back:
            time.sleep(0)  # let the executor thread take commands between ticks
            return deadline
        deadline += 1.0 / self.rate_hz
        delay = deadline - time.monotonic()
        if delay > 0:
            stopping.wait(delay)
            return deadline
        return time.monotonic()  # a late tick: no burst of ticks to catch up

    # --- stamps -----------------------------------------------------------------------------
    def now_ns(self) -> int:
        """Now on the node's clock: simulated time when it publishes /clock, ROS time otherwise."""
        if self.publishes:
            return round(self.sim.t * 1e9)
        if not self.follows:
            return time.time_ns()  # ROS time without use_sim_time is the system clock (cheaper to read)
        return self.ros_clock.now().nanoseconds

    def sim_instant_ns(self) -> int:
        """The node-clock time of the simulated instant now (integer ns: float seconds of the
        epoch would round it to a quarter of a microsecond)."""
        return self.origin_ns + round(self.sim.t * 1e9)

    def state_stamp_ns(self) -> int:
        """The header stamp of the state now: the node-clock time of this simulated instant
        (command stamps map back through the same origin, so a state and a command stamped
        alike mean one instant). Where simulated time runs at another pace than ROS time
        (real_time_factor other than 1, without publish_clock), the time it is published."""
        if self.publishes:
            return round(self.sim.t * 1e9)
        if self.follows or self.rtf == 1.0:
            return self.sim_instant_ns()
        return self.now_ns()

    def stamp_to_sim_time(self, stamp: Any) -> float | None:
        """Simulated time a command stamp means; None for a zero (unset) stamp."""
        if stamp.sec == 0 and stamp.nanosec == 0:
            return None
        return (stamp.sec * 1_000_000_000 + stamp.nanosec - self.origin_ns) * 1e-9

    def received_s(self) -> float:
        """Simulated time of now, by the log time the bag keeps (for stale commands)."""
        return (self.now_ns() - self.origin_ns) * 1e-9
