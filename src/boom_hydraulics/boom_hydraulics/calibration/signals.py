"""The recorded signals a calibration matches, read from a bag at their recorded log times.

A real machine's bag carries its sensors on the standard topics, each message logged when it
arrived, at no fixed step: the rod position in ``sensor_msgs/JointState`` (the
``cylinder_joint`` entry, as the node publishes it on ``joint_states``) and the chamber
pressures in ``sensor_msgs/FluidPressure`` (topics ending in ``piston_pressure`` and
``rod_pressure``). A bag of boom_sim or boom-resim also holds DriveState, which every other
signal comes from and which stands in where a standard topic is missing.

Each sample is compared at the instant it shows: its header stamp, where the signal's stamps
are on the run's clock (each within ``STAMP_SLACK_S`` of the recording's span; the node
stamps every message with the simulated instant it shows, a machine's driver with when it
sampled), else its log time. The node logs a message up to a tick after its stamp: compared
at their log times, a re-simulation that reproduces the run exactly misses it by up to
0.1 mm and 0.04 MPa, which a fit takes for the model's and which biases what it fits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError

from ..bags.encoding import DRIVE_STATE, DRIVE_STATE_FIELDS, FLAGS
from ..bags.reading import check_bag_path
from ..errors import BagError, ConfigError
from ..model.outputs import OUTPUTS
from ..model.robot_description import JOINTS

JOINT_STATE = "sensor_msgs/msg/JointState"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
ROD_JOINT = JOINTS[2]  # cylinder_joint: q1
#: The signals a calibration can match (DriveState's numbers), with their units.
UNITS = {name: unit for name, unit, _ in OUTPUTS if name in DRIVE_STATE_FIELDS.values() and name not in FLAGS}
#: The standard sensor topic of a signal: (message type, topic name ending).
SENSORS = {
    "q1": (JOINT_STATE, "joint_states"),
    "p1": (FLUID_PRESSURE, "piston_pressure"),
    "p2": (FLUID_PRESSURE, "rod_pressure"),
}
_FIELD = {output: field for field, output in DRIVE_STATE_FIELDS.items()}
#: Stamps count as on the run's clock within this of the recording's span, s.
STAMP_SLACK_S = 1.0


@dataclass(frozen=True)
class Signal:
    """One recorded signal: its samples at their log times."""

    name: str
    log_ns: np.ndarray  # int64, on the recording's clock
    values: np.ndarray  # SI (UNITS)
    topic: str
    stamp_ns: np.ndarray | None = None  # int64: the header stamps, where they are on the run's clock

    @property
    def time_ns(self) -> np.ndarray:
        """The instant each sample shows: its stamp where usable, else its log time."""
        return self.log_ns if self.stamp_ns is None else self.stamp_ns

    @property
    def clock(self) -> str:
        """'stamps' or 'log times': what :attr:`time_ns` is."""
        return "log times" if self.stamp_ns is None else "stamps"


def check_names(names: Sequence[str]) -> None:
    """ConfigError for a signal name that cannot be matched."""
    for name in names:
        if name not in UNITS:
            raise ConfigError(f"--signals {name}: not a recorded signal; choose from {', '.join(UNITS)}")


def _sensor_value(name: str, msg: object) -> float | None:
    if name == "q1":
        names = list(msg.name)
        return float(msg.position[names.index(ROD_JOINT)]) if ROD_JOINT in names else None
    return float(msg.fluid_pressure)


def _stamp_ns(msg: object) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def read_signals(bag: Path, names: Sequence[str], span_ns: tuple[int, int] | None = None) -> dict[str, Signal]:
    """The signals ``names`` of ``bag``, each from its standard sensor topic or else DriveState,
    with their header stamps where all of them lie within ``span_ns`` (the run's origin and
    end, widened by STAMP_SLACK_S; None: the bag's span); BagError naming a signal the bag
    does not hold."""
    check_bag_path(bag)
    check_names(names)
    samples: dict[str, tuple[list[int], list[float], str]] = {}
    try:
        with AnyReader([bag]) as reader:
            for name in names:
                kind, ending = SENSORS.get(name, (None, None))
                sensors = [c for c in reader.connections if c.msgtype == kind and c.topic.endswith(ending)]
                states = [c for c in reader.connections if c.msgtype == DRIVE_STATE]
                connections = sensors[:1] or states[:1]
                if not connections:
                    continue
                times, values, stamps = [], [], []
                for connection, log_ns, raw in reader.messages(connections=connections):
                    msg = reader.deserialize(raw, connection.msgtype)
                    value = (
                        float(getattr(msg, _FIELD[name]))
                        if connection.msgtype == DRIVE_STATE
                        else _sensor_value(name, msg)
                    )
                    if value is not None:
                        times.append(log_ns)
                        values.append(value)
                        stamps.append(_stamp_ns(msg))
                samples[name] = (times, values, stamps, connections[0].topic)
            span_ns = span_ns or (int(reader.start_time), int(reader.end_time))
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
    out = {}
    for name in names:
        times, values, stamps, topic = samples.get(name, ([], [], [], ""))
        if len(times) < 2:
            where = f"{SENSORS[name][0]} on */{SENSORS[name][1]} or " if name in SENSORS else ""
            raise BagError(f"{bag}: no recorded {name} ({where}{DRIVE_STATE}); choose --signals the bag holds")
        stamps = np.array(stamps, dtype=np.int64)
        slack = round(STAMP_SLACK_S * 1e9)
        usable = bool(np.all((stamps >= span_ns[0] - slack) & (stamps <= span_ns[1] + slack)))
        time_ns = stamps if usable else np.array(times, dtype=np.int64)
        order = np.argsort(time_ns, kind="stable")
        out[name] = Signal(
            name,
            np.array(times, dtype=np.int64)[order],
            np.array(values, dtype=float)[order],
            topic,
            stamps[order] if usable else None,
        )
    return out


def start_ns(bag: Path) -> int:
    """The log time of the bag's first message (the time origin of a bag without a run description)."""
    try:
        with AnyReader([bag]) as reader:
            return int(reader.start_time)
    except AnyReaderError as exc:
        raise BagError(f"{bag}: cannot read the bag ({exc}); is it truncated or not a rosbag2/MCAP bag?") from None
