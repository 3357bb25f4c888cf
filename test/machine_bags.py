"""Bags as a machine would record them, made from the model with known parameters.

The "machine" is the model itself (a Simulator driven by the node's command rule, stepped
at 0.1 ms), so that a calibration has a known answer. Its bag has the valve commands as
ValveCommand messages and the sensors on the standard topics: the rod position in
JointState (cylinder_joint) and the chamber pressures in FluidPressure, each logged at its
own time, jittered around its rate, with Gaussian noise. With ``describe`` it also carries
the node's run description (the parameters it ran with), as a boom_sim bag does.

``record_node`` records as the node does: DriveState at its publish rate, each stamped with
the simulated instant it shows and logged a little later, the commands taken at the node's
ticks, with the run description; noise on its rod position and pressures, and a reset where
asked.
"""

from __future__ import annotations

import bisect
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from boom_hydraulics.bags import cdr
from boom_hydraulics.bags.encoding import DRIVE_STATE, drive_state_cdr
from boom_hydraulics.bags.recording import BagRecorder, Topic, run_description
from boom_hydraulics.model.parameters import from_mapping
from boom_hydraulics.model.robot_description import JOINTS
from boom_hydraulics.solve.command_queue import CommandedDrive
from boom_hydraulics.solve.simulation import Simulator

#: Where the recording starts on the machine's clock (an epoch time, as on a real machine), ns.
EPOCH_NS = 1_795_000_000_000_000_000
TOPICS = {
    "valve_command": "boom_hydraulics_msgs/msg/ValveCommand",
    "joint_states": "sensor_msgs/msg/JointState",
    "piston_pressure": "sensor_msgs/msg/FluidPressure",
    "rod_pressure": "sensor_msgs/msg/FluidPressure",
}
#: A lift, a hold, a lowering and a hold: (time s, opening).
CYCLE = ((0.2, 1.0), (1.0, 0.0), (1.6, -0.6), (2.3, 0.0))


def valve_command(stamp_ns: int, opening: float) -> bytes:
    """boom_hydraulics_msgs/ValveCommand (header, float64 opening); stamp 0: apply on arrival."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return cdr.layout(("i", "I", "I", ("s", 1), "d")).pack(cdr.ENCAPSULATION, sec, nanosec, 1, b"\0", opening)


def record_machine(
    folder: Path,
    truth: Mapping[str, Any] = (),
    commands: Sequence[tuple[float, float]] = CYCLE,
    duration_s: float = 3.0,
    rate_hz: float | Mapping[str, float] = 100.0,
    jitter_s: float = 3e-3,
    noise: Mapping[str, float] = (),
    describe: bool = False,
    seed: int = 7,
) -> Path:
    """Record the machine with parameters ``truth`` (over the defaults) through ``commands``:
    sensors at about ``rate_hz`` each (a number, or one per signal q1, p1, p2), log times
    jittered by up to +-``jitter_s``, Gaussian ``noise`` per signal (q1 m, p1 and p2 Pa).
    Returns the bag folder."""
    rng = np.random.default_rng(seed)
    params = from_mapping(dict(truth))
    fine = from_mapping({"time_step_s": 1e-4}, base=params)
    sim = Simulator(fine)
    drive = CommandedDrive(sim, 0.0)
    for at_s, opening in commands:
        drive.push(at_s, opening)
    noise = {"q1": 0.0, "p1": 0.0, "p2": 0.0} | dict(noise)
    samples = []  # (log s, topic, signal)
    rates = rate_hz if isinstance(rate_hz, Mapping) else dict.fromkeys(("q1", "p1", "p2"), rate_hz)
    for topic, signal in (("joint_states", "q1"), ("piston_pressure", "p1"), ("rod_pressure", "p2")):
        n = int(duration_s * rates[signal])
        t = np.arange(n) / rates[signal] + np.concatenate([[0.0], rng.uniform(-jitter_s, jitter_s, n - 1)])
        samples += [(float(s), topic, signal) for s in t]  # the first at 0: the recording starts at rest
    samples.sort()
    custom = run_description(params, EPOCH_NS, 100.0, 0.0, node="/boom_sim") if describe else None
    with BagRecorder(folder, [Topic(f"/{n}", t) for n, t in TOPICS.items()], custom_data=custom) as rec:
        pending = sorted(commands)
        out = sim.outputs()
        for at_s, topic, signal in samples:
            while pending and pending[0][0] <= at_s:
                command_s, opening = pending.pop(0)
                rec.write("/valve_command", EPOCH_NS + round(command_s * 1e9), valve_command(0, opening))
            steps = round((at_s - sim.t) / fine.time_step_s)
            if steps > 0:
                drive.advance(steps)
                out = sim.outputs()
            value = float(out[signal]) + rng.normal(0.0, noise[signal]) if noise[signal] else float(out[signal])
            log_ns = EPOCH_NS + round(at_s * 1e9)
            if topic == "joint_states":
                data = cdr.joint_state(log_ns, JOINTS, [0.0, 0.0, value], [0.0, 0.0, 0.0], [])
            else:
                data = cdr.fluid_pressure(log_ns, topic, value)
            rec.write(f"/{topic}", log_ns, data)
    return folder


def record_node(
    folder: Path,
    truth: Mapping[str, Any] = (),
    commands: Sequence[tuple[float, float]] = CYCLE,
    duration_s: float = 3.0,
    rate_hz: float = 100.0,
    lag_s: tuple[float, float] = (1e-4, 1.5e-3),
    noise: Mapping[str, float] = (),
    reset_at_s: float | None = None,
    seed: int = 7,
) -> Path:
    """Record as boom_sim does with parameters ``truth`` (over the defaults) through
    ``commands`` (log time s, opening; unstamped): its run description, and DriveState on
    /drive_state every 1/``rate_hz`` s, stamped with the simulated instant it shows and logged
    ``lag_s`` (uniform between the two) later, with Gaussian ``noise`` on its q1 (m), p1 and p2
    (Pa). A command is taken, as the node takes it, at the instant of the last state logged
    before it. At ``reset_at_s`` the drive is reset (back at rest at its initial length, its
    energies from 0), as ~/reset does. Returns the bag folder."""
    rng = np.random.default_rng(seed)
    params = from_mapping(dict(truth))
    sim = Simulator(params)
    drive = CommandedDrive(sim, 0.0)
    n = int(duration_s * rate_hz)
    stamps_s = np.arange(1, n + 1) / rate_hz
    logs_s = stamps_s + rng.uniform(*lag_s, n)
    for at_s, opening in commands:
        k = bisect.bisect_left(logs_s.tolist(), at_s)
        drive.push(float(stamps_s[k - 1]) if k else 0.0, opening)
    noise = {"q1": 0.0, "p1": 0.0, "p2": 0.0} | dict(noise)
    fields = {"q1": "q1", "p1": "p1", "p2": "p2"}
    custom = run_description(params, EPOCH_NS, rate_hz, 0.0, node="/boom_sim")
    topics = [Topic("/valve_command", TOPICS["valve_command"]), Topic("/drive_state", DRIVE_STATE)]
    with BagRecorder(folder, topics, custom_data=custom) as rec:
        pending = sorted(commands)
        for stamp_s, log_s in zip(stamps_s, logs_s):
            while pending and pending[0][0] <= log_s:
                command_s, opening = pending.pop(0)
                rec.write("/valve_command", EPOCH_NS + round(command_s * 1e9), valve_command(0, opening))
            if reset_at_s is not None and stamp_s > reset_at_s:
                sim.reset(keep_time=True)
                drive.reset()
                reset_at_s = None
            drive.advance(round((stamp_s - sim.t) / params.time_step_s))
            out = dict(sim.outputs())
            for signal, field in fields.items():
                if noise[signal]:
                    out[field] = float(out[field]) + rng.normal(0.0, noise[signal])
            stamp_ns = EPOCH_NS + round(stamp_s * 1e9)
            rec.write("/drive_state", EPOCH_NS + round(log_s * 1e9), drive_state_cdr(out, stamp_ns))
    return folder


def params_file(path: Path, values: Mapping[str, Any]) -> Path:
    """A params YAML of the defaults with ``values`` (what boom-calibrate starts from)."""
    from boom_hydraulics.model import config
    from boom_hydraulics.model.parameters import as_dict

    path.write_text(config.dumps(as_dict(from_mapping(dict(values)))))
    return path
