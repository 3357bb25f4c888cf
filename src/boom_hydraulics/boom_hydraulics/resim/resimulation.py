"""A recorded session's valve commands fed into the model again, "what if" (``boom-resim``).

The bag's own parameters (stored by the node) are the base; --config replaces them, --set
changes single ones. Parameters changed while the node ran (recorded from its
/parameter_events) change at the same simulated instants here, with the --set values kept
on top. Commands apply by the node's rule (command_queue): at their header stamp, or, if
unstamped or already passed, at the simulated instant the node took them; with its command
timeout. The node takes commands between ticks, and each tick ends with a DriveState: that
instant is the last state's logged before the command (recorded.NodeInstants), also where
the node fell behind its clock. The new bag has a DriveState at each instant the node
published one (rounded to the steps of a changed time_step_s), on the recorded topic (a
namespaced run stays namespaced), and the original commands and parameter events, so both
runs overlay sample for sample; its states are logged at the times the node published
them, so that a re-simulation of it finds the same instants. Exact for runs on the node's
own clock at real time, with publish_clock, and on use_sim_time (where the node takes
commands at the states it published, and logs what it handles at one clock reading 1 ns
apart, in order; before it did, a command's time was known to within one publish period).
What the node did to its own time line (resets, pauses, steps, resumes, dropped backlogs)
it recorded as run events (bags.run_events): each state, command and parameter change
maps to simulated time through the time origin it was stamped with, and the drive is reset
where the node reset it. A bag from before the node recorded its events is refused (exit 2) where its drive was
reset or, on ROS-time stamps, it was paused, resumed or stepped (see refusals and
bags.continuity); a bag with its events only where it is not whole. A run that cannot be
simulated to its end writes nothing; an interrupted one (Ctrl-C: exit 130, SIGTERM: 143)
neither, and a killed one's temporary folder is removed by the next run to the same --out.

Where the node's position controller drove the valve (MoveBoom goals, ~/joint_trajectory,
joint_commands), the bag holds each path the controller started to follow (~/setpoint_path,
where the node took it: between ticks, as a command) and its setpoint (~/setpoint, every tick
in which it drove). The controller follows the recorded paths here, the same knots at the same
simulated times, bit for bit, each from this run's own setpoint (or boom angle) where the node's
started from its own, so that an unchanged run reproduces the node's exactly and a changed one
moves from where its boom is; with the new parameters' gains and cylinder. It lets go where the
setpoints show the node's let go (a canceled goal). A bag from before the node recorded its
paths has only the setpoints: the controller follows them (cubic between ticks, from where the
boom was when control began), close to the recording but not to the last bit. The new bag has
the paths and the setpoints of this run, so that a re-simulation of it follows them again.
"""

from __future__ import annotations

import math
import shutil
import sys
from collections import deque
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..bags.encoding import (
    DRIVE_STATE,
    ENERGY_LEDGER,
    START_BOOM,
    START_SETPOINT,
    RecordedPath,
    drive_state_cdr,
    setpoint_cdr,
)
from ..bags.energy import energy_ledger_cdr, finite, ledger_every, ledger_now
from ..bags.reading import read_run_description
from ..bags.recording import BagRecorder, Topic
from ..bags.run_description import RunDescription
from ..bags.run_events import EVENTS_TYPE, RunEvent
from ..errors import ConfigError, RecordingError, SimulationError
from ..files import check_apart, folder_beside
from ..model import config
from ..model.parameters import NAMES, from_mapping
from ..model.robot_description import JOINTS
from ..model.setpoints import LINEAR, SetpointPath, path_from_offsets
from ..programs import raise_pending
from ..solve.command_queue import CommandedDrive, stale, valve_opening
from ..solve.simulation import Simulator
from .control import Control, control_stretches
from .recorded import JOINT_STATE, Recorded, RecordedRun, TakenPath, read_run
from .refusals import check_calls, check_states
from .staging import remove_stale_staging


class _Resimulation:
    """The recorded run's commands and parameter changes through a simulator."""

    def __init__(self, run: RecordedRun, values: Mapping[str, Any], overrides: Mapping[str, Any]) -> None:
        self.run, self.overrides = run, dict(overrides)
        self.sim = Simulator(from_mapping(values))
        self.drive = CommandedDrive(self.sim, run.command_timeout_s)
        self.pending = deque(run.parameter_changes)
        # commands wait here for the instant the node took them (see take); without drive states
        # they are queued at once, each for when it was logged or stamped
        taken: list[Recorded | TakenPath] = [c for c in run.commands if c.taken_ns is not None]
        # and so do the paths the controller started to follow (taken between ticks as commands are)
        taken += run.paths
        self.waiting = deque(sorted(taken, key=lambda c: (c.taken_after, c.log_ns)))
        for command in run.commands:
            if command.taken_ns is None:
                self._push(command, self.seconds(command.at_ns, command.origin_ns))

    def seconds(self, at_ns: int, origin_ns: int | None = None) -> float:
        """Simulated time of a time on the node's clock, through the time origin ``origin_ns``
        (default the run's first)."""
        return (at_ns - (self.run.clock_origin_ns if origin_ns is None else origin_ns)) * 1e-9

    def _timeout_at(self, log_ns: int) -> float:
        """The command timeout in effect when a message logged at ``log_ns`` arrived (the
        recorded changes of it included, by their own log times: both on the node's clock)."""
        timeout_s = self.run.command_timeout_s
        for change in self.run.parameter_changes:
            if change.log_ns <= log_ns and "command_timeout_s" in change.changes:
                timeout_s = float(change.changes["command_timeout_s"])
        return timeout_s

    def _push(self, command: Recorded, at_s: float) -> None:
        u = valve_opening(command.opening, self.sim.params.mode)
        if u is None:
            return
        origin = command.origin_ns
        if command.stamp_ns and stale(
            self.seconds(command.stamp_ns, origin),
            self.seconds(command.log_ns, origin),
            self._timeout_at(command.log_ns),
        ):
            return  # the node refused it as stale when it arrived
        self.drive.push(at_s, u)

    def take(self, states: int, logged_before: float = math.inf) -> None:
        """The commands the node took after publishing ``states`` drive states (or before),
        those logged before ``logged_before``, queued as the node queued them (ros.commands):
        at their stamp, or now if unstamped; a passed stamp acts at the next step, and the
        command timeout counts from it. The paths its controller took meanwhile are followed
        from now, in the order the node logged them among the commands."""
        while self.waiting and self.waiting[0].taken_after <= states and self.waiting[0].log_ns < logged_before:
            command = self.waiting.popleft()
            if isinstance(command, TakenPath):
                self.follow(command.path)
                continue
            at_s = self.seconds(command.stamp_ns, command.origin_ns) if command.stamp_ns else self.sim.t
            self._push(command, at_s)

    def to(self, t_s: float, stopped: bool = False) -> None:
        """Step on to simulated time ``t_s``; ``stopped``: the node's simulation stopped on a
        failure before it got there, and stood still (a failure here stops it as well)."""
        steps = round((t_s - self.sim.t) / self.sim.params.time_step_s)
        if steps <= 0:
            return
        try:
            self.drive.advance(steps)
        except SimulationError:
            if not stopped:
                raise

    def event(self, event: RunEvent) -> None:
        """A run event of the node: a reset puts the drive back to rest (at the recorded rod
        position; the state of these parameters there) where the node reset it; the others
        move the time origin or stop the clock, which the recorded stamps already tell."""
        if event.event != "reset":
            return
        self.to(event.sim_time_s, event.stopped)
        self.sim.reset(event.rod_position_m, keep_time=True)
        self.drive.reset()

    def take_over(self, control: Control, origins: Mapping[int, int]) -> None:
        """The controller drives from now along the recorded setpoints (from where the boom is),
        each stamped as the state of its tick (``origins``: the time origin of a state stamp)."""
        angle, rate = self.drive.setpoint()
        times = [self.sim.t] + [self.seconds(ns, origins.get(ns)) for ns, _, _ in control.samples]
        angles = [angle] + [a for _, a, _ in control.samples]
        rates = [rate] + [r for _, _, r in control.samples]
        self.drive.follow(SetpointPath.of(times, angles, rates))

    def follow(self, recorded: RecordedPath) -> None:
        """The controller follows a path the node's controller started to follow here: its knots
        after now, as the node timed them (model.setpoints.path_from_offsets: the same path, bit
        for bit, at the node's instant), its first knot where the node took it from: this run's
        setpoint or boom angle, which are the node's in a run that reproduces it, and this
        run's own with new parameters (a move from where the boom is here)."""
        angles, rates = list(recorded.angles_rad), list(recorded.rates_rad_s)
        if recorded.start == START_SETPOINT:
            angle, rate = self.drive.setpoint()
            angles[0] = angle
            if recorded.order != LINEAR:
                rates[0] = rate
        elif recorded.start == START_BOOM:
            angles[0] = float(self.sim.outputs()["alpha"])
        self.drive.follow(path_from_offsets(self.sim.t, recorded.offsets_ns, angles, rates, recorded.order))

    def apply_changes(self) -> None:
        """Parameter changes due by now (the node applies them between ticks)."""
        half_step = 0.5 * self.sim.params.time_step_s
        while self.pending and self.seconds(self.pending[0].at_ns, self.pending[0].origin_ns) <= self.sim.t + half_step:
            changes = self.pending.popleft().changes
            model = {k: v for k, v in changes.items() if k in NAMES and k not in self.overrides}
            if model:
                try:
                    self.sim.set_parameters(from_mapping(model, base=self.sim.params))
                except ConfigError as exc:
                    raise ConfigError(f"a recorded parameter change does not fit the new parameters: {exc}") from None
                self.drive.parameters_changed()  # as the node: the controller takes the new gains and constants
            if "command_timeout_s" in changes:
                self.drive.timeout_s = float(changes["command_timeout_s"])


def _grid(run: RecordedRun, time_step_s: float) -> list[int]:
    """State instants at the recorded publish rate, for a bag without DriveState."""
    tick_s = max(1, round(1.0 / (run.publish_rate_hz * time_step_s))) * time_step_s
    n_ticks = int((run.end_ns - run.clock_origin_ns) * 1e-9 / tick_s)
    return [run.clock_origin_ns + round((k + 1) * tick_s * 1e9) for k in range(n_ticks)]


def _around(instants: list[int], origin_ns: int, read_at_s: np.ndarray) -> list[int]:
    """The instants of a grid next to each of the times ``read_at_s`` (s from ``origin_ns``): the
    two that linear interpolation at it reads (np.interp on the whole grid takes the same two,
    so it gives the same values), one at either end of the grid. A run of the same steps that
    stops to give its state less often: a fit of a real machine's bag, its sensors read
    together at 100 Hz, on a grid of 1 ms steps takes a fifth of the instants."""
    at_s = (np.array(instants, dtype=np.int64) - origin_ns).astype(float) * 1e-9  # as the fit reads them
    after = np.searchsorted(at_s, read_at_s, side="right")
    taken = np.union1d(np.clip(after - 1, 0, len(instants) - 1), np.clip(after, 0, len(instants) - 1))
    return [instants[k] for k in taken]


def _progress(total: int):
    """A progress bar over the state instants, as boom-sweep shows it: on stderr, only when
    it is a terminal."""
    from tqdm import tqdm

    return tqdm(total=total, unit="state", disable=None, file=sys.stderr, leave=False)


def _write_failure(out: Path, recorder: BagRecorder) -> RecordingError:
    """The one line for a new bag the disk did not take (full, I/O error): its name and the cause."""
    cause = (recorder.error or "").removeprefix(f"{recorder.file}: ").split("; recording stopped")[0]
    return RecordingError(
        f"{out}: cannot write the new bag ({cause or 'the disk failed'}); nothing was written. "
        f"Free space in {out.parent} or choose another --out"
    )


def read_recorded(
    bag: Path, config_file: Path | None = None, prog: str = "boom-resim", description: RunDescription | None = None
) -> tuple[RecordedRun, dict[str, Any]]:
    """The recorded run of ``bag`` and the parameter values to simulate it with: the bag's own,
    or ``config_file``'s. ``description`` stands in for a bag without one (not recorded by
    boom_sim). Raises ConfigError for a run that cannot be re-simulated (see refusals)."""
    description = description or read_run_description(bag)
    check_calls(bag, description)
    run = read_run(bag, description)
    check_states(bag, run)
    values = dict(run.parameters) if config_file is None else config.read_values(config_file)
    retired = sorted(name for name in values if name not in NAMES) if config_file is None else []
    if retired:  # recorded by an earlier version of the model: what it no longer has cannot apply
        print(
            f"{prog}: note: {bag} holds parameters this version no longer has ({', '.join(retired)}); "
            "they are left out, and the model's defaults stand in for what replaced them",
            file=sys.stderr,
        )
        values = {name: value for name, value in values.items() if name in NAMES}
    return run, values


class Replay:
    """A recorded run's commands, parameter changes and controller paths (or, in an older bag,
    its setpoints) through the model with parameter ``values`` (``overrides`` kept on top of the
    recorded changes). Iterating it
    runs the simulation and gives (stamp ns, outputs) at each state instant the node published
    (or, for a bag without DriveState, at its publish rate); ``done`` counts the instants taken.
    Raises SimulationError where the run cannot go on, ConfigError for a recorded parameter
    change that does not fit the new parameters. For a bag without DriveState, ``read_at_s``
    (s from the run's time origin) gives the states only at the steps around those times (a
    fit's recorded samples), where linear interpolation reads them."""

    def __init__(
        self, run: RecordedRun, values: Mapping[str, Any], overrides: Mapping[str, Any] = (),
        read_at_s: np.ndarray | None = None,
    ) -> None:  # fmt: skip
        self.run = run
        self._resim = _Resimulation(run, dict(values) | dict(overrides), overrides)
        self.params = self._resim.sim.params
        self.instants = run.state_ns or _grid(run, self.params.time_step_s)
        if read_at_s is not None and not run.state_ns:
            self.instants = _around(self.instants, run.clock_origin_ns, read_at_s)
        # the time origin each instant is stamped with, and when the node published its state
        # (the grid's: at its instant)
        self.origins = run.state_origins_ns() or [run.clock_origin_ns] * len(self.instants)
        self.state_log_ns = run.state_log_ns or self.instants
        self.instant_ns = run.clock_origin_ns  # the instant of the state just given
        self.index = 0  # its index in instants
        self.done = 0

    def setpoint(self) -> tuple[float, float] | None:
        """The controller's setpoint (rad, rad/s) at the state just given, where it drove in the
        steps up to it (as the node publishes it on ~/setpoint); None where it did not."""
        followed = self._resim.drive.followed
        return None if followed is None else followed.at(self.sim.t)

    @property
    def sim(self) -> Any:
        """The simulation at the state just given (solve.simulation.Simulator)."""
        return self._resim.sim

    def __iter__(self) -> Iterator[tuple[int, dict[str, Any]]]:
        run, resim = self.run, self._resim
        stretches = control_stretches(run.setpoints, self.instants)
        starts = {c.start_ns: c for c in stretches}
        releases = {c.release_ns for c in stretches if c.release_ns != self.instants[-1]}
        events = deque(zip(run.events, (log for log, _ in run.event_messages)))
        stamp_origins = dict(zip(self.instants, self.origins))  # (the setpoints' stamps are their states')
        now_ns = run.clock_origin_ns
        for index, at_ns in enumerate(self.instants):
            self.done += 1  # the recorded run's state instants: runs overlay sample for sample
            resim.apply_changes()  # the node changes parameters between ticks, at a state instant
            # and takes commands and makes its events between ticks, in the order it logged them
            happened = False
            while events and events[0][0].states_before <= index:
                event, log_ns = events.popleft()
                resim.take(index, log_ns)
                resim.event(event)
                happened = True
            resim.take(index)
            if now_ns in starts and not run.paths:  # a goal or trajectory was taken between these instants
                resim.take_over(starts[now_ns], stamp_origins)
            origin = self.origins[index]
            steps = round((resim.seconds(at_ns, origin) - resim.sim.t) / resim.sim.params.time_step_s)
            # an instant that rounds onto the last one (a longer time_step_s): what comes there acts
            # from here; where the run has events, it is given again, so that the new bag has a
            # state for each recorded one (a reset publishes the instant again)
            if steps <= 0 and not (happened or run.has_events):
                now_ns = at_ns
                continue
            if steps > 0:
                resim.drive.advance(steps)  # a SimulationError ends it
            if at_ns in releases and resim.drive.loop is not None:  # let go at the end of this tick
                resim.drive.let_go()
            now_ns = self.instant_ns = at_ns
            self.index = index
            yield origin + round(resim.sim.t * 1e9), resim.sim.outputs()


def resimulate(
    bag: Path, out: Path, config_file: Path | None = None, overrides: Mapping[str, Any] = ()
) -> tuple[Path, int]:
    """Write a new bag of the recorded commands through the model with the new parameters;
    returns the bag and its DriveState count. Raises SimulationError if the run stops early,
    ConfigError if the run cannot be re-simulated (see refusals)."""
    check_apart(out, [bag] + ([config_file] if config_file else []))
    if out.exists():
        raise ConfigError(f"--out {out} exists already; name a new bag folder")
    for folder in remove_stale_staging(out):
        print(f"boom-resim: note: removed {folder}, left by an earlier run to {out} that was killed", file=sys.stderr)
    run, values = read_recorded(bag, config_file)
    replay = Replay(run, values, overrides)
    events_topic = run.description.events_topic
    custom = RunDescription.of(
        replay.params,
        run.clock_origin_ns,
        run.publish_rate_hz,
        run.command_timeout_s,
        resimulated_from=str(bag),
        events_topic=events_topic,
    ).to_custom_data()
    # the commands, parameter changes and run events as recorded: a re-simulation of the new bag
    # finds them as in this one
    events = [Recorded(0, log_ns, events_topic, raw) for log_ns, raw in run.event_messages] if events_topic else []
    events += [Recorded(0, p.log_ns, p.topic, p.raw) for p in run.paths]
    recorded = deque(sorted(run.commands + run.parameter_changes + events, key=lambda r: r.log_ns))
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = folder_beside(out)  # (an error names --out, not the staging folder)
    try:
        # the energy ledger at ENERGY_HZ, where the run has one (physical mode, a topic to put it on)
        energy_topic = run.energy_topic if replay.params.mode == "physical" else None
        energy_every = ledger_every(run.publish_rate_hz)
        topics = [Topic(run.state_topic, DRIVE_STATE), *run.topics]
        topics += [Topic(events_topic, EVENTS_TYPE)] if events_topic else []
        topics += [Topic(energy_topic, ENERGY_LEDGER)] if energy_topic else []
        setpoint_topic = run.setpoint_topic  # (where the node had one: a re-simulation of the new bag lets go there)
        topics += [Topic(setpoint_topic, JOINT_STATE)] if setpoint_topic else []
        with (
            BagRecorder(staging / "bag", topics, custom_data=custom, file_stem=out.name) as recorder,
            _progress(len(replay.instants)) as progress,
        ):
            for stamp_ns, outputs in replay:
                raise_pending()  # a Ctrl-C or SIGTERM whose exception a finalizer swallowed stops it here
                progress.update(replay.done - progress.n)
                # logged when the node published the state of this instant, so that a re-simulation
                # of this bag finds the node's instants as in the recorded run (NodeInstants)
                log_ns = replay.state_log_ns[replay.index]
                while recorded and recorded[0].log_ns <= log_ns:  # the recorded messages, in log order
                    message = recorded.popleft()
                    recorder.write(message.topic, message.log_ns, message.raw)
                recorder.write(run.state_topic, log_ns, drive_state_cdr(outputs, stamp_ns))
                setpoint = replay.setpoint()
                if setpoint_topic and setpoint is not None:
                    recorder.write(setpoint_topic, log_ns, setpoint_cdr(JOINTS[0], *setpoint, stamp_ns))
                if energy_topic and replay.done % energy_every == 0:
                    sim = replay.sim
                    now = ledger_now(sim.params, sim.t, sim.y, sim.constants, sim.u)
                    if now is not None and finite(now):
                        recorder.write(energy_topic, log_ns, energy_ledger_cdr(now, stamp_ns))
                if recorder.error is not None:  # the disk failed: stop here, nothing is kept
                    break
        if recorder.error is not None or not getattr(recorder, "finished", True):
            raise _write_failure(out, recorder)
        (staging / "bag").rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # created by this run
    return out, recorder.counts[run.state_topic]
