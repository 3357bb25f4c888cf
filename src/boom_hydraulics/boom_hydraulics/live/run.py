"""One live run: the model stepped in real time as the node steps it, its topics, its steering.

The node's stepping without ROS: a :class:`~..solve.simulation.Simulator` under a
:class:`~..solve.command_queue.CommandedDrive` (the stamp rule, the command timeout, the
position controller), paced by a :class:`.clock.LiveClock`; each tick publishes what the
node publishes (the state topics at every tick, the setpoint while the controller drives,
the markers at 20 Hz, the diagnostics once a second) through a sink, plus the frames
robot_state_publisher would send, and for a target angle the path the controller starts to
follow. Valve commands, target angles and parameter sets come in from other threads (the
server's callbacks); one lock keeps them and the ticks apart.

Nothing here knows the WebSocket server: it hands (outlet, CDR bytes, log time) to the
sink and one-line notices to the notifier.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from foxglove import Parameter

from ..bags import messages
from ..bags.diagnostics import CommandCounts, RunCounts, diagnostics
from ..bags.encoding import START_SETPOINT, RecordedPath, message, setpoint_cdr, setpoint_path_cdr, to_cdr
from ..errors import ConfigError, SimulationError
from ..model.geometry import outside_stroke
from ..model.parameters import Parameters
from ..model.robot_description import JOINTS, TIP_JOINT, urdf
from ..model.setpoints import move, on_whole_ns
from ..solve.command_queue import CommandedDrive, stale, valve_opening
from ..solve.simulation import Simulator
from . import parameters as live_parameters
from .channels import (
    DESCRIPTION,
    DIAGNOSTICS,
    DRIVE,
    FORCE,
    HINGE,
    MARKERS,
    PATH,
    PISTON,
    ROD,
    SETPOINT,
    TF,
    TF_STATIC,
    Outlet,
)
from .channels import JOINTS as JOINT_STATES
from .clock import LiveClock
from .frames import Joint, joints, moving_frames, static_frames
from .recording import LiveRecording
from .steering import Steer

#: The state topics in the order of :func:`~..bags.messages.state_messages` (the markers after them).
STATE_OUTLETS = (DRIVE, JOINT_STATES, PISTON, ROD, FORCE, HINGE)
MARKERS_HZ = 20.0  # as the node: markers are for eyes, not for control
DIAGNOSTICS_PERIOD_S = 1.0  # wall time, as the node's timer
NOTICE_PERIOD_S = 1.0  # the same notice goes to stderr at most this often

#: (outlet, CDR bytes, log time ns): where a run's messages go.
Sink = Callable[[Outlet, bytes, int], None]
#: (level 0 info, 1 warning, 2 error; the notice's kind; one line): what a client is told.
Notifier = Callable[[int, str, str], None]


class LiveRun:
    """The simulation of one live session and what it publishes (see the module docstring)."""

    def __init__(
        self,
        params: Parameters,
        sink: Sink,
        notify: Notifier,
        *,
        real_time_factor: float = 1.0,
        rate_hz: float = 100.0,
        command_timeout_s: float = 0.0,
        max_catch_up_s: float = 0.2,
        jit: bool | None = None,
    ) -> None:
        self.sim = Simulator(params, jit=jit)
        self.sim.warm()  # compile (or load from the cache) what it steps with, before the clock starts
        self.drive = CommandedDrive(self.sim, command_timeout_s)
        self.clock = LiveClock(self.sim, rate_hz, real_time_factor, max_catch_up_s)
        self.sink, self._notify = sink, notify
        self.lock = threading.RLock()
        self.failure: str | None = None
        self.counts = CommandCounts()
        self.recording: LiveRecording | None = None
        self.started = False
        self._markers_every = max(1, round(rate_hz / MARKERS_HZ))
        self._ticks = 0
        self._diagnosed_at = -math.inf
        self._noticed: dict[str, float] = {}
        self._joints = joints(urdf(params))
        self._messages = messages.TickMessages(params)
        # the first message of a type has rosbags build its serialiser: before the clock starts
        self._state(self.sim.published(), 0, markers=True)
        self._latched(params, 0)
        self._diagnostics(0)

    # --- start and finish ---------------------------------------------------------------
    def start(self, record: Path | None = None) -> None:
        """Simulated time 0 is now; the bag, if asked for, starts here; the robot description
        and the fixed frames go out."""
        with self.lock:
            self.clock.restart()
            if record is not None:
                p = self.sim.params
                self.recording = LiveRecording(
                    record, p, self.clock.origin_ns, self.clock.rate_hz, self.drive.timeout_s
                )
            self.publish_description()
            self.publish_diagnostics()
            self.started = True

    def finish(self) -> tuple[Path, str, str | None] | None:
        """Finish the bag, if recording: (its folder, messages per topic, the error that stopped it or None)."""
        return None if self.recording is None else self.recording.finish()

    # --- publishing -------------------------------------------------------------------------
    def _out(self, items: Iterable[tuple[Outlet, bytes]], log_ns: int) -> None:
        """Hand the messages to the sink, then record them: a tick is recorded whole."""
        items = list(items)
        for outlet, data in items:
            self.sink(outlet, data, log_ns)
        if self.recording is not None:
            for outlet, data in items:
                if outlet.recorded:
                    self.recording.write(outlet.topic, log_ns, data)

    @staticmethod
    def _latched(params: Parameters, now_ns: int) -> tuple[list[tuple[Outlet, bytes]], list[Joint]]:
        """The URDF of ``params`` for robot_description and its fixed frames for /tf_static;
        and its joints."""
        description = urdf(params)
        urdf_joints = joints(description)
        string = to_cdr(message("std_msgs/msg/String", data=description))
        return [(DESCRIPTION, string), (TF_STATIC, static_frames(urdf_joints, now_ns))], urdf_joints

    def publish_description(self) -> None:
        """robot_description and /tf_static, at the start and after a parameter change."""
        now = self.clock.now_ns()
        latched, self._joints = self._latched(self.sim.params, now)
        self._out(latched, now)

    def resend_latched(self, topic: str) -> None:
        """A client subscribed to a latched topic: send its last message again (as transient
        local does; the bag has it once, from when it was published). Without the lock: the
        server calls this from its own threads, and the parameters are one immutable object."""
        now = self.clock.now_ns()
        for outlet, data in self._latched(self.sim.params, now)[0]:
            if outlet.topic == topic:
                self.sink(outlet, data, now)

    def _state(self, values: list[float], stamp_ns: int, markers: bool) -> list[tuple[Outlet, bytes]]:
        """The messages of the state ``values`` (``Simulator.published()``): the state topics,
        the setpoint while the controller drives, the markers if asked for, and the moving frames."""
        if self._messages.params is not self.sim.params:  # new parameters: new dimensions for the markers
            self._messages = messages.TickMessages(self.sim.params)
        tick = list(zip((*STATE_OUTLETS, MARKERS), self._messages.state(values, stamp_ns, markers)))
        if self.drive.followed is not None:  # the controller drove in this tick: its setpoint now
            tick.append((SETPOINT, setpoint_cdr(JOINTS[0], *self.drive.followed.at(self.sim.t), stamp_ns)))
        c = messages.joints(values)
        at = dict(zip(JOINTS, (c.boom_rad, c.barrel_rad, c.rod_m)))
        at[TIP_JOINT] = values[messages.AT["boom_deflection"]]  # the elastic boom's tip (a moving joint where it is on)
        tick.append((TF, moving_frames(self._joints, at, stamp_ns)))
        return tick

    def publish_state(self) -> None:
        """The state now, stamped with its instant (markers every few ticks)."""
        values = self.sim.published()
        if not messages.finite(values):  # (the battery's outputs are NaN in paper mode: not among them)
            return  # a NaN never reaches a topic
        self._ticks += 1
        tick = self._state(values, self.clock.state_stamp_ns(), self._ticks % self._markers_every == 0)
        self._out(tick, self.clock.now_ns())

    def _diagnostics(self, stamp_ns: int) -> bytes:
        clock = self.clock
        recording = self.recording.status() if self.recording is not None else None
        args = (clock.pacer, clock.rate_hz, clock.rtf, self.counts, RunCounts(), clock.origin_shift_s, recording)
        return diagnostics(stamp_ns, self.sim, self.failure, False, *args)

    def publish_diagnostics(self) -> None:
        stamp_ns = self.clock.now_ns()
        self._out([(DIAGNOSTICS, self._diagnostics(stamp_ns))], stamp_ns)

    # --- ticks ------------------------------------------------------------------------------
    def tick(self) -> None:
        """Take the steps due now and publish the state; the diagnostics once a second; a
        recording that failed (a full disk) said at once, in one line, as the node says it."""
        with self.lock:
            if self.failure is None:
                self._step()
            if self.recording is not None and (error := self.recording.failed_now()) is not None:
                self.notice(2, "recording", f"recording stopped: {error}; the simulation goes on")
                self.publish_diagnostics()
            if time.monotonic() - self._diagnosed_at >= DIAGNOSTICS_PERIOD_S:
                self._diagnosed_at = time.monotonic()
                self.publish_diagnostics()

    def _step(self) -> None:
        tick = self.clock.due()
        if tick.dropped_s:
            self.notice(1, "real-time", f"{tick.dropped_s:.3f} s behind real time; dropping the backlog")
        if tick.steps <= 0:
            return
        try:
            self.drive.advance(tick.steps)
        except SimulationError as exc:
            self.failure = str(exc)
            self.notice(2, "simulation", f"simulation stopped: {exc}; restart boom-sim live to run again")
            return
        self.publish_state()
        self.clock.pacer.settled(self.sim.step_count, self.sim.params.time_step_s)

    def fail(self, why: str) -> None:
        """Stop the simulation (an unexpected error in a tick), reported as a blow-up is."""
        with self.lock:
            self.failure = why
        self.notice(2, "simulation", f"simulation stopped: {why}")

    # --- steering ---------------------------------------------------------------------------
    def notice(self, level: int, kind: str, text: str) -> None:
        """Tell the clients (a notice replaces the last one of its ``kind``) and stderr (at most
        once a second per kind)."""
        self._notify(level, kind, text)
        now = time.monotonic()
        if now - self._noticed.get(kind, -math.inf) >= NOTICE_PERIOD_S:
            self._noticed[kind] = now
            print(f"boom-sim live: {('note', 'warning', 'error')[level]}: {text}", file=sys.stderr, flush=True)

    def on_message(self, steer: Steer, data: bytes) -> None:
        """One message on a steering channel (from a server thread)."""
        value, stamp_ns = steer.read(data)  # SteeringError: the caller tells the client
        with self.lock:
            if steer.steers_valve:
                received_ns = self.clock.now_ns()
                if self.recording is not None:  # recorded as received, as the node does
                    self.recording.command(steer.topic, received_ns, steer.recorded(value, stamp_ns, data))
                self._valve(value, stamp_ns, received_ns)
            else:
                self._target(value)

    def _valve(self, opening: float, stamp_ns: int, received_ns: int) -> None:
        """A valve opening by the node's rule: clamped to the mode's range, acting at its stamp
        (0: now) unless already older than the command timeout."""
        drive = self.drive
        u = valve_opening(opening, self.sim.params.mode)
        if u is None:
            self.notice(1, "valve", f"ignored non-finite valve opening {opening}")
            return
        if u != opening:
            self.notice(1, "valve", f"valve opening {opening:g} clamped to {u:g}")
        self.counts.received += 1
        at_s = self.clock.to_sim_s(stamp_ns) if stamp_ns else None
        if at_s is not None and stale(at_s, self.clock.to_sim_s(received_ns), drive.timeout_s):
            self.counts.stale += 1
            self.notice(1, "valve", "ignored a valve command older than the command timeout; stamp it 0 (now)")
            return
        if not drive.push(self.sim.t if at_s is None else at_s, u):
            self.counts.refused += 1
            self.notice(1, "valve", "too many future-stamped valve commands waiting; refused")

    def _target(self, angle_deg: float) -> None:
        """Move the boom to ``angle_deg`` with the position controller, as a MoveBoom goal does."""
        p = self.sim.params
        target = math.radians(angle_deg) if math.isfinite(angle_deg) else math.nan
        why = (
            "position control needs mode: physical (paper mode's valve only lifts)"
            if p.mode != "physical"
            else f"the simulation stopped ({self.failure})"
            if self.failure
            else f"the target angle must be finite degrees, got {angle_deg}"
            if not math.isfinite(target)
            else outside_stroke(p, target)
        )
        if why is not None:
            self.notice(1, "target", f"target angle refused: {why}")
            return
        angle, rate = self.drive.setpoint()
        t = self.sim.t
        path = on_whole_ns(move(t, angle, rate, target, p.control_max_speed_rad_s), t)  # as the node's goals
        self.drive.follow(path)
        # on /boom_sim/setpoint_path and in the bag, as the node tells of a goal's path: boom-resim
        # follows it from its own setpoint at this instant (START_SETPOINT)
        told = RecordedPath.taken(path, t, self.clock.state_stamp_ns(), START_SETPOINT)
        self._out([(PATH, setpoint_path_cdr(JOINTS[0], told))], self.clock.now_ns())
        self.notice(0, "target", f"moving to {angle_deg:g} deg from {math.degrees(angle):.2f} deg")

    # --- parameters -------------------------------------------------------------------------
    def get_parameters(self, names: Iterable[str]) -> list[Parameter]:
        """The parameters named (all for none), as they are now (one immutable object: no lock)."""
        return live_parameters.current(self.sim.params, names)

    def set_parameters(self, requested: list[Parameter]) -> list[Parameter]:
        """Apply a client's set as a whole, or refuse it whole with one line; the values after it."""
        names = [p.name for p in requested]
        try:
            with self.lock:
                before = self.sim.params
                new = live_parameters.checked(before, requested)
            if self.sim.jit and (new.mode, new.method) != (before.mode, before.method):
                Simulator(new, jit=True).warm()  # compile (or load) the new kernels while the run goes on
            with self.lock:
                new = live_parameters.checked(self.sim.params, requested)  # against the parameters now
                self._apply(new, names)
        except ConfigError as exc:
            self.notice(2, "parameters", f"parameters not changed: {exc}")
        return self.get_parameters(names)

    def _apply(self, new: Parameters, names: list[str]) -> None:
        """Apply checked parameters between ticks; recorded at the instant they take effect at."""
        dt_before, steps_before = self.sim.params.time_step_s, self.sim.step_count
        self.sim.set_parameters(new)
        self.drive.parameters_changed()
        self.clock.rebase(dt_before, steps_before)
        if self.recording is not None:
            changed = live_parameters.events(new, names)
            self.recording.parameter_event(self.clock.now_ns(), self.clock.sim_instant_ns(), changed)
        self.publish_description()  # a dimension may have changed
        self.notice(0, "parameters", "parameters changed: " + ", ".join(f"{n}={getattr(new, n)}" for n in names))
