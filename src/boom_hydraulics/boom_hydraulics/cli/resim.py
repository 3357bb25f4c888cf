"""``boom-resim``: a recorded session's valve commands fed into the model again, "what if".

    boom-resim bags/20261122-044106_boom_sim --set piston_diameter_m=0.063 --set rod_diameter_m=0.036 \\
        --out bags/what_if_63mm
    boom-resim run.mcap --config config/default.yaml --set payload_mass_kg=150 --out bags/heavy

The bag's own parameters (stored by the node) are the base; --config replaces them, --set
changes single ones. Parameters changed while the node ran (recorded from its
/parameter_events) change at the same simulated instants here, with the --set values kept
on top. Commands apply by the node's rule (command_queue): at their header stamp, or when
received if unstamped or already passed; with its command timeout. The new bag has a
DriveState at each instant the node published one (rounded to the steps of a changed
time_step_s), on the recorded topic (a namespaced run stays namespaced), and the original
commands and parameter events, so both runs overlay sample for sample. Exact for runs
recorded with publish_clock; with ROS-time stamps a command's time is known to within one
publish period. A run whose drive was reset, or, on ROS-time stamps, paused, resumed or
stepped, is refused (exit 2): its time line is not one continuous line from its origin
(see bags.continuity). A run that cannot be simulated to its end writes nothing; an
interrupted one (Ctrl-C: exit 130, SIGTERM: 143) neither, and a killed one's temporary
folder is removed by the next run to the same --out.

Where the node's position controller drove the valve (MoveBoom goals, ~/joint_trajectory),
the bag holds its setpoint (~/setpoint, every tick): the controller follows the recorded
setpoints here too (cubic between ticks, from where the boom was when control began), with
the new parameters' gains and cylinder; it lets go where the recording shows it let go. The
setpoint between two ticks is interpolated, so such a run matches its recording closely but
not to the last bit.
"""

from __future__ import annotations

import math
import re
import shutil
import sys
import tempfile
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from rosbags.highlevel import AnyReader, AnyReaderError

from ..bags import continuity
from ..bags.encoding import DRIVE_STATE, drive_state_cdr
from ..bags.reading import read_custom_data
from ..bags.recording import BagRecorder, Topic, is_being_recorded, offered_qos, run_description
from ..errors import BagError, ConfigError, RecordingError
from ..files import check_apart
from ..model import config
from ..model.parameters import NAMES, from_mapping
from ..model.setpoints import SetpointPath
from ..solve.command_queue import CommandedDrive, stale, valve_opening
from ..solve.simulation import Simulator
from .common import RaisingParser, run_main, summary

VALVE_COMMAND = "boom_hydraulics_msgs/msg/ValveCommand"
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
#: The node's diagnostics status that counts resets, pauses and steps, and how far its origin moved.
RUN_STATUS = "boom_sim: run"
_RUN_KEYS = ("resets", "pauses", "step_calls", "clock_origin_shift_s")
JOINT_STATE = "sensor_msgs/msg/JointState"
ARRAY_COMMAND = "std_msgs/msg/Float64MultiArray"
PARAMETER_EVENT = "rcl_interfaces/msg/ParameterEvent"
#: ParameterValue.type -> the field that holds the value (rcl_interfaces/msg/ParameterType)
_VALUE_FIELDS = {
    1: "bool_value",
    2: "integer_value",
    3: "double_value",
    4: "string_value",
    5: "byte_array_value",
    6: "bool_array_value",
    7: "integer_array_value",
    8: "double_array_value",
    9: "string_array_value",
}


@dataclass
class Recorded:
    """One recorded message to copy into the new bag: when it acts, when it was logged."""

    at_ns: int  # on the node's clock: when it takes effect
    log_ns: int
    topic: str
    raw: bytes
    opening: float = math.nan  # commands
    changes: dict[str, Any] = field(default_factory=dict)  # parameter events
    stamp_ns: int = 0  # a ValveCommand's header stamp (0: unset)


@dataclass
class RecordedRun:
    """What a node recorded about its run, enough to run it again."""

    parameters: dict[str, Any]
    clock_origin_ns: int
    publish_rate_hz: float
    command_timeout_s: float
    end_ns: int
    state_topic: str
    state_ns: list[int]  # the instants the node published DriveState at
    topics: list[Topic]  # of the commands and parameter events, with their recorded offers
    commands: list[Recorded]
    parameter_changes: list[Recorded]
    setpoints: list[tuple[int, float, float]] = field(default_factory=list)  # (stamp ns, rad, rad/s)
    node: str | None = None  # the recording node's fully qualified name, where recorded
    # the node's own count of what breaks the time line (its "boom_sim: run" diagnostics), the latest
    run_counts: dict[str, float] = field(default_factory=dict)
    # the recorded drive states' q1, v, a and valve loss energy, in stamp order (reset detection)
    state_signals: tuple[list[float], ...] = ((), (), (), ())


#: The DriveState fields the reset detection reads (bags.continuity.reset_from_states).
_CONTINUITY_FIELDS = ("rod_position_m", "rod_velocity_m_s", "rod_acceleration_m_s2", "valve_loss_energy_j")


def _stamp_ns(msg: Any) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _messages(reader: AnyReader, connections: Sequence[Any]):
    """The messages of ``connections``, deserialised; none for no connections (rosbags reads an
    empty list as every connection)."""
    if not connections:
        return
    for connection, log_ns, raw in reader.messages(connections=connections):
        yield connection, log_ns, raw, reader.deserialize(raw, connection.msgtype)


def _parameter_value(value: Any) -> Any:
    field_name = _VALUE_FIELDS.get(value.type)
    if field_name is None:
        return None
    raw = getattr(value, field_name)
    return [v.item() if hasattr(v, "item") else v for v in raw] if field_name.endswith("array_value") else raw


def _run_values(values: Sequence[Any]) -> dict[str, float]:
    """The counts of a "boom_sim: run" status (KeyValue text), those that read as numbers."""
    out = {}
    for kv in values:
        if kv.key in _RUN_KEYS:
            try:
                out[kv.key] = float(kv.value)
            except ValueError:
                continue
    return out


def read_run(bag: Path) -> RecordedRun:
    """The parameters, time origin, valve commands and parameter changes a boom_sim node recorded."""
    custom = read_custom_data(bag)
    if custom is None:
        raise BagError(f"{bag}: no run description (custom data); was it recorded by boom_sim?")
    node_name = custom.get("node")
    try:
        with AnyReader([bag]) as reader:
            states = [c for c in reader.connections if c.msgtype == DRIVE_STATE]
            recorded_states = sorted(
                (_stamp_ns(msg), *(float(getattr(msg, name)) for name in _CONTINUITY_FIELDS))
                for _, _, _, msg in _messages(reader, states[:1])
            )
            wanted = [c for c in reader.connections if c.msgtype in (VALVE_COMMAND, ARRAY_COMMAND, PARAMETER_EVENT)]
            topics = [
                Topic(c.topic, c.msgtype, tuple(getattr(c.ext, "offered_qos_profiles", ())) or (offered_qos(),))
                for c in wanted
            ]
            setpoint_topics = [
                c for c in reader.connections if c.msgtype == JOINT_STATE and c.topic.endswith("/setpoint")
            ]
            setpoints = sorted(
                (_stamp_ns(msg), msg.position[0], msg.velocity[0])
                for _, _, _, msg in _messages(reader, setpoint_topics[:1])
            )
            run_counts: dict[str, float] = {}
            diagnostics = [c for c in reader.connections if c.msgtype == DIAGNOSTICS]
            for _, _, _, msg in _messages(reader, diagnostics):
                for status in msg.status:
                    if status.name == RUN_STATUS:
                        run_counts.update(_run_values(status.values))
            commands, changes = [], []
            for connection, log_ns, raw, msg in _messages(reader, wanted):
                if connection.msgtype == PARAMETER_EVENT:
                    if node_name and msg.node != node_name:
                        continue
                    values = {p.name: _parameter_value(p.value) for p in msg.changed_parameters}
                    at_ns = msg.stamp.sec * 1_000_000_000 + msg.stamp.nanosec
                    changes.append(Recorded(at_ns, log_ns, connection.topic, bytes(raw), changes=values))
                    continue
                if connection.msgtype == VALVE_COMMAND:
                    # the node's rule: at its stamp, or when received if unstamped or already passed
                    stamp_ns = _stamp_ns(msg)
                    opening, at_ns = msg.opening, max(stamp_ns, log_ns)
                else:
                    stamp_ns, opening, at_ns = 0, (msg.data[0] if len(msg.data) == 1 else math.nan), log_ns
                commands.append(
                    Recorded(at_ns, log_ns, connection.topic, bytes(raw), float(opening), stamp_ns=stamp_ns)
                )
            end_ns = reader.end_time
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (ValueError, KeyError, IndexError, AttributeError) as exc:  # a message of another layout than its type
        raise BagError(
            f"{bag}: a message does not fit its recorded type ({exc!r}); was it recorded by boom_sim?"
        ) from None
    try:
        return RecordedRun(
            parameters=yaml.safe_load(custom["parameters"]),
            clock_origin_ns=int(custom["clock_origin_ns"]),
            publish_rate_hz=float(custom["publish_rate_hz"]),
            command_timeout_s=float(custom["command_timeout_s"]),
            end_ns=end_ns,
            state_topic=states[0].topic if states else "/drive_state",
            state_ns=[row[0] for row in recorded_states],
            topics=topics,
            commands=commands,
            parameter_changes=sorted(changes, key=lambda r: r.at_ns),
            setpoints=setpoints,
            node=node_name,
            run_counts=run_counts,
            state_signals=tuple(list(column) for column in zip(*recorded_states))[1:] or ((), (), (), ()),
        )
    except (KeyError, ValueError, yaml.YAMLError) as exc:
        raise BagError(f"{bag}: the recorded run description is unreadable ({exc})") from None


_WHY = "a re-simulation replays the commands on one continuous time line from the run's origin"


def check_calls(bag: Path) -> None:
    """Raise ConfigError, saying why, if the node recorded calls of its services that broke the
    run's time line: a reset jumps the state; on ROS-time stamps (a node without publish_clock)
    a pause, resume or step also moved the node's time origin. With publish_clock the stamps
    are simulated time itself, which pauses and steps do not break: those runs are re-simulated.
    Read before the rest of the bag, from the recorded custom data and the events alone."""
    custom = read_custom_data(bag) or {}
    try:
        origin_ns = int(custom.get("clock_origin_ns", "0"))
    except ValueError:
        return  # read_run names the unreadable description
    sim_time = origin_ns == 0  # publish_clock: simulated time 0 is stamp 0
    calls = continuity.recorded_calls(bag, custom.get("node"), origin_ns)
    breaking = ("reset",) if sim_time else tuple(continuity.SERVICES)
    found = continuity.Calls({s: n for s, n in calls.counts.items() if s in breaking}, calls.first_s)
    if found.total():
        fix = "Record the run without resets" + (
            "" if sim_time else ", pauses or steps, or with publish_clock:=true, whose time line pauses and steps keep"
        )
        what = f"the run was {continuity.describe(found)}"
        raise ConfigError(f"{bag}: {what}; {_WHY}, so it cannot reproduce this run. {fix}")


def check_counts(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError if the node's own diagnostics count resets, or, on ROS-time stamps,
    pauses, steps or a moved time origin (a resume, a dropped backlog)."""
    counts = run.run_counts
    sim_time = run.clock_origin_ns == 0
    found = continuity.Calls()
    found.counts = {"reset": int(counts.get("resets", 0))}
    if not sim_time:
        found.counts.update(pause=int(counts.get("pauses", 0)), step=int(counts.get("step_calls", 0)))
    if found.total():
        what = f"the node counted {continuity.describe(found, with_times=False)} in its diagnostics"
        raise ConfigError(f"{bag}: {what}; {_WHY}, so it cannot reproduce this run. Record the run without them")
    shift_s = counts.get("clock_origin_shift_s", 0.0)
    if not sim_time and abs(shift_s) > 0.5e-6:
        raise ConfigError(
            f"{bag}: the node's time origin moved by {shift_s:.6f} s during the run (it was resumed, or fell behind "
            f"real time and dropped the backlog); {_WHY}, so it cannot reproduce this run. Record it with "
            "publish_clock:=true, whose stamps are simulated time"
        )


def check_states(bag: Path, run: RecordedRun) -> None:
    """Raise ConfigError if the recorded drive states show a reset (for bags from before the
    node recorded its service calls, and for a reset by a ROS clock that jumped back)."""
    check_counts(bag, run)
    if not run.state_ns:
        return
    k = continuity.reset_from_states(run.state_ns, *run.state_signals)
    if k is not None:
        t = (run.state_ns[k] - run.clock_origin_ns) * 1e-9
        raise ConfigError(
            f"{bag}: the run appears to have been reset at t = {t:.3f} s (the energy dissipated in its valve, "
            f"counted since start or reset, dropped, or the rod jumped further than it can move); {_WHY}, so it "
            "cannot reproduce this run. Record the run without resets"
        )


class _Resimulation:
    """The recorded run's commands and parameter changes through a simulator."""

    def __init__(self, run: RecordedRun, values: Mapping[str, Any], overrides: Mapping[str, Any]) -> None:
        self.run, self.overrides = run, dict(overrides)
        self.sim = Simulator(from_mapping(values))
        self.drive = CommandedDrive(self.sim, run.command_timeout_s)
        self.pending = deque(run.parameter_changes)
        for command in run.commands:
            self._push(command)

    def seconds(self, at_ns: int) -> float:
        """Simulated time of a time on the node's clock."""
        return (at_ns - self.run.clock_origin_ns) * 1e-9

    def _timeout_at(self, at_ns: int) -> float:
        """The command timeout in effect at ``at_ns`` (the recorded changes of it included)."""
        timeout_s = self.run.command_timeout_s
        for change in self.run.parameter_changes:
            if change.at_ns <= at_ns and "command_timeout_s" in change.changes:
                timeout_s = float(change.changes["command_timeout_s"])
        return timeout_s

    def _push(self, command: Recorded) -> None:
        u = valve_opening(command.opening, self.sim.params.mode)
        if u is None:
            return
        if command.stamp_ns and stale(
            self.seconds(command.stamp_ns), self.seconds(command.log_ns), self._timeout_at(command.log_ns)
        ):
            return  # the node refused it as stale when it arrived
        self.drive.push(self.seconds(command.at_ns), u)

    def take_over(self, control: Control) -> None:
        """The controller drives from now along the recorded setpoints (from where the boom is)."""
        angle, rate = self.drive.setpoint()
        times = [self.sim.t] + [self.seconds(ns) for ns, _, _ in control.samples]
        angles = [angle] + [a for _, a, _ in control.samples]
        rates = [rate] + [r for _, _, r in control.samples]
        self.drive.follow(SetpointPath.of(times, angles, rates))

    def apply_changes(self) -> None:
        """Parameter changes due by now (the node applies them between ticks)."""
        half_step = 0.5 * self.sim.params.time_step_s
        while self.pending and self.seconds(self.pending[0].at_ns) <= self.sim.t + half_step:
            changes = self.pending.popleft().changes
            model = {k: v for k, v in changes.items() if k in NAMES and k not in self.overrides}
            if model:
                try:
                    self.sim.set_parameters(from_mapping(model, base=self.sim.params))
                except ConfigError as exc:
                    raise ConfigError(f"a recorded parameter change does not fit the new parameters: {exc}") from None
            if "command_timeout_s" in changes:
                self.drive.timeout_s = float(changes["command_timeout_s"])


@dataclass(frozen=True)
class Control:
    """A stretch of the run in which the position controller drove the valve."""

    start_ns: int  # the state instant at which it took over (the one before its first setpoint)
    samples: list[tuple[int, float, float]]  # the recorded setpoints
    release_ns: int  # the state instant of its last setpoint: the controller had let go there, unless
    # the recording ends there


def control_stretches(setpoints: Sequence[tuple[int, float, float]], instants: Sequence[int]) -> list[Control]:
    """The recorded setpoints cut into stretches of consecutive ticks, each placed on the state
    instants: control began at the instant before its first setpoint, and the node publishes a
    setpoint for every tick in which the controller drove, so it had let go (canceled, or taken
    over by a valve command) by the instant of the last one."""
    position = {ns: k for k, ns in enumerate(instants)}
    stretches: list[list[tuple[int, float, float]]] = []
    for sample in setpoints:
        k = position.get(sample[0])
        if k is None:
            continue
        if stretches and position[stretches[-1][-1][0]] == k - 1:
            stretches[-1].append(sample)
        else:
            stretches.append([sample])
    out = []
    for samples in stretches:
        first = position[samples[0][0]]
        start = instants[first - 1] if first > 0 else samples[0][0]
        out.append(Control(start, samples, samples[-1][0]))
    return out


def _grid(run: RecordedRun, time_step_s: float) -> list[int]:
    """State instants at the recorded publish rate, for a bag without DriveState."""
    tick_s = max(1, round(1.0 / (run.publish_rate_hz * time_step_s))) * time_step_s
    n_ticks = int((run.end_ns - run.clock_origin_ns) * 1e-9 / tick_s)
    return [run.clock_origin_ns + round((k + 1) * tick_s * 1e9) for k in range(n_ticks)]


#: An unfinished staging folder this old, with no live bag in it, was left by a killed run (s).
STALE_AFTER_S = 60.0


def _staging_pattern(out: Path) -> re.Pattern[str]:
    """The names of the staging folders of runs to ``out``: ``.NAME.xxxxxxxx.partial`` (tempfile.mkdtemp)."""
    return re.compile(rf"\.{re.escape(out.name)}\.[A-Za-z0-9_]{{8}}\.partial")


def _left_by_a_killed_run(folder: Path) -> bool:
    """A staging folder of ours whose run is gone: no MCAP file in it is held by a live
    recorder, and it has one (or is old enough that its run would have made one)."""
    mcaps = list(folder.glob("*/*.mcap"))
    if any(is_being_recorded(f) for f in mcaps):
        return False
    return bool(mcaps) or time.time() - folder.stat().st_mtime > STALE_AFTER_S


def remove_stale_staging(out: Path) -> list[Path]:
    """Remove the staging folders that killed runs (SIGKILL, power loss) to this same ``out``
    left beside it; only folders of this tool's own pattern for ``out``. Returns them."""
    if not out.parent.is_dir():
        return []
    pattern = _staging_pattern(out)
    removed = []
    for folder in sorted(out.parent.iterdir()):
        if folder.is_dir() and not folder.is_symlink() and pattern.fullmatch(folder.name):
            if _left_by_a_killed_run(folder):
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
    return removed


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


def resimulate(
    bag: Path, out: Path, config_file: Path | None = None, overrides: Mapping[str, Any] = ()
) -> tuple[Path, int]:
    """Write a new bag of the recorded commands through the model with the new parameters;
    returns the bag and its DriveState count. Raises SimulationError if the run stops early,
    ConfigError if the run cannot be re-simulated (reset, or paused on ROS-time stamps)."""
    check_apart(out, [bag] + ([config_file] if config_file else []))
    if out.exists():
        raise ConfigError(f"--out {out} exists already; name a new bag folder")
    for folder in remove_stale_staging(out):
        print(f"boom-resim: note: removed {folder}, left by an earlier run to {out} that was killed", file=sys.stderr)
    check_calls(bag)
    run = read_run(bag)
    check_states(bag, run)
    values = dict(run.parameters) if config_file is None else config.read_values(config_file)
    retired = sorted(name for name in values if name not in NAMES) if config_file is None else []
    if retired:  # recorded by an earlier version of the model: what it no longer has cannot apply
        print(
            f"boom-resim: note: {bag} holds parameters this version no longer has ({', '.join(retired)}); "
            "they are left out, and the model's defaults stand in for what replaced them",
            file=sys.stderr,
        )
        values = {name: value for name, value in values.items() if name in NAMES}
    values.update(dict(overrides))
    resim = _Resimulation(run, values, overrides)
    params = resim.sim.params
    instants = run.state_ns or _grid(run, params.time_step_s)
    custom = run_description(
        params, run.clock_origin_ns, run.publish_rate_hz, run.command_timeout_s, resimulated_from=str(bag)
    )
    recorded = deque(sorted(run.commands + run.parameter_changes, key=lambda r: r.log_ns))
    stretches = control_stretches(run.setpoints, instants)
    starts = {c.start_ns: c for c in stretches}
    releases = {c.release_ns for c in stretches if c.release_ns != instants[-1]}
    now_ns = run.clock_origin_ns
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        topics = [Topic(run.state_topic, DRIVE_STATE), *run.topics]
        with (
            BagRecorder(staging / "bag", topics, custom_data=custom, file_stem=out.name) as recorder,
            _progress(len(instants)) as progress,
        ):
            for at_ns in instants:
                progress.update()  # the recorded run's state instants: runs overlay sample for sample
                steps = round((resim.seconds(at_ns) - resim.sim.t) / resim.sim.params.time_step_s)
                if steps <= 0:
                    continue
                resim.apply_changes()  # the node changes parameters between ticks, at a state instant
                if now_ns in starts:  # a goal or trajectory was taken between these instants
                    resim.take_over(starts[now_ns])
                resim.drive.advance(steps)  # a SimulationError ends it: nothing is written
                if at_ns in releases and resim.drive.loop is not None:  # let go at the end of this tick
                    resim.drive.let_go()
                now_ns = at_ns
                stamp_ns = run.clock_origin_ns + round(resim.sim.t * 1e9)
                while recorded and recorded[0].log_ns <= stamp_ns:  # the recorded messages, in log order
                    message = recorded.popleft()
                    recorder.write(message.topic, message.log_ns, message.raw)
                recorder.write(run.state_topic, stamp_ns, drive_state_cdr(resim.sim.outputs(), stamp_ns))
                if recorder.error is not None:  # the disk failed: stop here, nothing is kept
                    break
        if recorder.error is not None or not getattr(recorder, "finished", True):
            raise _write_failure(out, recorder)
        (staging / "bag").rename(out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # created by this run
    return out, recorder.counts[run.state_topic]


def main(argv: Sequence[str] | None = None) -> int:
    def body() -> int:
        parser = RaisingParser(prog="boom-resim", description=summary(__doc__))
        parser.add_argument("bag", type=Path, help="bag folder or .mcap file recorded by boom_sim")
        parser.add_argument("--config", type=Path, help="params YAML replacing the recorded parameters")
        parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="change one parameter")
        parser.add_argument("--out", type=Path, required=True, help="new bag folder (must not exist)")
        args = parser.parse_args(argv)
        overrides = dict(config.parse_assignment(s) for s in args.set)
        folder, states = resimulate(args.bag, args.out, args.config, overrides)  # Ctrl-C, SIGTERM: nothing kept
        print(f"boom-resim: {states} drive states in {folder}")
        return 0

    return run_main("boom-resim", body)


if __name__ == "__main__":
    sys.exit(main())
