"""``boom-resim``: a recorded session's valve commands fed into the model again, "what if".

    boom-resim bags/20261122-044106_boom_sim --set piston_diameter_m=0.063 --set rod_diameter_m=0.036 \
        --out bags/what_if_63mm
    boom-resim run.mcap --config config/default.yaml --set payload_mass_kg=150 --out bags/heavy

The bag's own parameters (stored by the node) are the base; ``--config`` replaces them,
``--set`` changes single ones. Commands apply at their recorded times by the node's rule
(command_queue), with its command timeout; the new bag has DriveState at the recorded
publish rate and the original commands. Exact for runs recorded with ``publish_clock``;
with ROS-time stamps a command's time is known to within one publish period, and a run
that was reset or paused cannot be replayed this way (the time origin moved).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from rclpy.time import Time
from rosbags.highlevel import AnyReader, AnyReaderError

from . import config
from .bag_reading import BagError, check_bag_path
from .command_queue import CommandedDrive, valve_opening
from .errors import BoomHydraulicsError, SimulationError
from .messages import drive_state
from .parameters import from_mapping
from .recording import CUSTOM_DATA_RECORD, BagRecorder, Topic, run_description
from .simulation import Simulator

VALVE_COMMAND = "boom_hydraulics_msgs/msg/ValveCommand"
ARRAY_COMMAND = "std_msgs/msg/Float64MultiArray"


@dataclass
class RecordedRun:
    """What a node recorded about its run, enough to run it again."""

    parameters: dict[str, Any]
    clock_origin_ns: int
    publish_rate_hz: float
    command_timeout_s: float
    end_ns: int
    commands: list[tuple[int, str, str, bytes, float]]  # (log ns, topic, msgtype, CDR, opening)


def _mcap_file(bag: Path) -> Path:
    if bag.is_file():
        return bag
    files = sorted(bag.glob("*.mcap"))
    if not files:
        raise BagError(f"{bag}: no .mcap file in this bag folder")
    return files[0]


def read_run(bag: Path) -> RecordedRun:
    """The parameters, time origin and valve commands a boom_sim node recorded in ``bag``."""
    check_bag_path(bag)
    try:
        with _mcap_file(bag).open("rb") as handle:
            custom = next(
                (m.metadata for m in make_reader(handle).iter_metadata() if m.name == CUSTOM_DATA_RECORD), None
            )
        if custom is None:
            raise BagError(f"{bag}: no '{CUSTOM_DATA_RECORD}' metadata; was it recorded by boom_sim?")
        with AnyReader([bag]) as reader:
            connections = [c for c in reader.connections if c.msgtype in (VALVE_COMMAND, ARRAY_COMMAND)]
            commands = []
            for connection, log_ns, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                opening = (
                    msg.opening
                    if connection.msgtype == VALVE_COMMAND
                    else (msg.data[0] if len(msg.data) == 1 else math.nan)
                )
                commands.append((log_ns, connection.topic, connection.msgtype, bytes(raw), float(opening)))
            end_ns = reader.end_time
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    except (KeyError, ValueError, yaml.YAMLError) as exc:
        raise BagError(f"{bag}: the recorded run description is unreadable ({exc})") from None
    return RecordedRun(
        parameters=yaml.safe_load(custom["parameters"]),
        clock_origin_ns=int(custom["clock_origin_ns"]),
        publish_rate_hz=float(custom["publish_rate_hz"]),
        command_timeout_s=float(custom["command_timeout_s"]),
        end_ns=end_ns,
        commands=commands,
    )


def resimulate(bag: Path, out: Path, config_file: Path | None = None, overrides: Mapping[str, Any] = ()) -> tuple:
    """Write a new bag of the recorded commands through the model with the new parameters."""
    run = read_run(bag)
    values = dict(run.parameters) if config_file is None else config.read_values(config_file)
    values.update(dict(overrides))
    params = from_mapping(values)
    sim = Simulator(params)
    drive = CommandedDrive(sim, run.command_timeout_s)
    for log_ns, _, _, _, opening in run.commands:
        u = valve_opening(opening, params.mode)
        if u is not None:
            drive.push((log_ns - run.clock_origin_ns) * 1e-9, u)
    per_tick = max(1, round(1.0 / (run.publish_rate_hz * params.time_step_s)))
    tick_s = per_tick * params.time_step_s
    n_ticks = int((run.end_ns - run.clock_origin_ns) * 1e-9 / tick_s)
    topics = [Topic("/drive_state", "boom_hydraulics_msgs/msg/DriveState")]
    topics += [Topic(t, m, reliable=False) for t, m in sorted({(c[1], c[2]) for c in run.commands})]
    custom = run_description(
        params, run.clock_origin_ns, run.publish_rate_hz, run.command_timeout_s, resimulated_from=str(bag)
    )
    stopped = None
    pending = list(run.commands)
    with BagRecorder(out, topics, custom_data=custom) as recorder:
        for _ in range(n_ticks):
            try:
                drive.advance(per_tick)
            except SimulationError as exc:
                stopped = str(exc)
                break
            stamp_ns = run.clock_origin_ns + round(sim.t * 1e9)
            while pending and pending[0][0] <= stamp_ns:  # the commands, in time order
                log_ns, topic, _, raw, _ = pending.pop(0)
                recorder.write(topic, log_ns, raw)
            msg = drive_state(sim.outputs(), Time(nanoseconds=stamp_ns).to_msg())
            recorder.write("/drive_state", stamp_ns, serialize_message(msg))
    return recorder.folder, recorder.counts["/drive_state"], stopped


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="boom-resim", description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path, help="bag folder or .mcap file recorded by boom_sim")
    parser.add_argument("--config", type=Path, help="params YAML replacing the recorded parameters")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="change one parameter")
    parser.add_argument("--out", type=Path, required=True, help="new bag folder (must not exist)")
    args = parser.parse_args(argv)
    try:
        overrides = dict(config.parse_assignment(s) for s in args.set)
        folder, states, stopped = resimulate(args.bag, args.out, args.config, overrides)
    except BoomHydraulicsError as exc:
        print(f"boom-resim: error: {exc}", file=sys.stderr)
        return 1
    print(f"boom-resim: {states} drive states in {folder}" + (f"; the run stopped early: {stopped}" if stopped else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
